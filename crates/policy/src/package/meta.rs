//! `model.json`: what a package declares, read and checked before any network
//! is opened. Its closed sets (the variant, the decoder branches, the
//! direction filter) are enums, so an unknown name is refused by the parser
//! with the names it accepts.
use super::pkg_err;
use crate::error::{PolicyError, Result};
use crate::observation::CHANNELS;
use std::path::Path;

/// Largest model.json read (the shipped ones are a few KB).
const MAX_META_BYTES: u64 = 1 << 20;
/// Largest input side a package may declare (the paper's images are 480x640).
pub const MAX_SIDE: usize = 2048;
/// Largest embedding width a package may declare.
pub const MAX_EMBEDDING: usize = 1 << 16;
/// The model.json format this runtime reads.
pub const FORMAT_VERSION: u32 = 1;

/// The observation a package's networks take.
#[derive(Clone, Debug, serde::Deserialize, serde::Serialize)]
pub struct InputSpec {
    /// Rows.
    pub height: usize,
    /// Columns.
    pub width: usize,
    /// Channels per pixel (10).
    pub channels: usize,
}

/// The three networks' file names, beside model.json.
#[derive(Clone, Debug, serde::Deserialize, serde::Serialize)]
pub struct Files {
    /// PositionNet.
    pub position: String,
    /// DirectionNet's image encoders.
    pub direction_encoder: String,
    /// DirectionNet's action decoder.
    pub direction_decoder: String,
    /// JointNet, optional (beyond the paper): per-pixel joint type, axis and
    /// origin, from which [`crate::frame_joint`] reads the grasped part's
    /// joint in one frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint: Option<String>,
}

/// The method a package was trained as (the paper's UMPNet or one of its
/// baselines); informational: the runtime acts on [`ModelMeta::branches`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Variant {
    /// UMPNet: Dist and AoT branches, trained on sequences.
    #[default]
    Umpnet,
    /// UMPNet trained on single steps only.
    SingleStep,
    /// The AoT branch alone.
    AotOnly,
    /// One signed distance instead of Dist and AoT.
    SignedDist,
    /// Where2Act-style: does this action move the object at all.
    Where2act,
    /// Regresses the direction from the current and goal observations.
    Inverse,
}

/// One decoder output a package declares in `branches`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Branch {
    /// The distance a direction would move the part.
    Dist,
    /// Arrow-of-Time class probabilities.
    Aot,
    /// One signed distance.
    SignedDist,
    /// The probability that the action moves the object.
    Binary,
    /// A regressed direction toward the reference observation.
    Inverse,
}

/// Which candidate directions the runtime rules out before CEM chooses:
/// the heuristics of the paper's `+HP` baselines, usable with any package.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DirectionFilter {
    /// Every direction may be chosen.
    #[default]
    None,
    /// Only directions within 90 degrees of the surface normal at the grasp
    /// (pull, never push into the part).
    Normal90,
    /// Only directions within 90 degrees of the previous action (the
    /// paper's Where2Act+HP and UMPNet+HP): no back-and-forth. Exploration
    /// only: a goal may lie behind the last move.
    Prev90,
    /// Only directions within 45 degrees of the line the grasped part moves
    /// along at the gripper, by the joint the package's JointNet reads from
    /// the episode's first frame (beyond the paper; a package with a
    /// JointNet only). Forward or back stays the Dist and AoT heads' call.
    Joint45,
    /// Goal task only: only directions within 45 degrees of the way from
    /// where the current frame shows the part to where the goal frame shows
    /// it, read off the two frames' geometry (beyond the paper; any
    /// package). It takes the Arrow-of-Time head's forward-or-back call; the
    /// Dist head ranks the directions kept. Where the gripper's own last
    /// motion agrees with that way, its motion is the way: it follows a
    /// hinge's arc where the frames give its chord.
    Goal45,
    /// Exploration only: after a move that carried the gripper more than
    /// 2 cm, only directions within 45 degrees of where it went, called
    /// forward (beyond the paper; any package). Otherwise `joint45`'s rule
    /// where the package's JointNet read the joint, else the heads.
    Onward45,
}

impl DirectionFilter {
    /// Every filter, in the order the help lists them.
    pub const ALL: [DirectionFilter; 6] = [
        Self::None,
        Self::Normal90,
        Self::Prev90,
        Self::Joint45,
        Self::Goal45,
        Self::Onward45,
    ];

    /// Whether the filter's rule reads the grasped part's joint from the
    /// grasp frame (the package's JointNet): front ends read it once, after
    /// the grasp, and hand it to every decision of the episode.
    pub fn reads_joint(self) -> bool {
        matches!(self, Self::Joint45 | Self::Onward45)
    }

    /// The name in model.json's `direction_filter` and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Normal90 => "normal90",
            Self::Prev90 => "prev90",
            Self::Joint45 => "joint45",
            Self::Goal45 => "goal45",
            Self::Onward45 => "onward45",
        }
    }
}

impl std::str::FromStr for DirectionFilter {
    type Err = PolicyError;
    fn from_str(s: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| {
                PolicyError::Input(format!(
                    "unknown direction filter `{s}`; expected none, normal90, prev90, joint45, goal45 or onward45"
                ))
            })
    }
}

/// How the runtime picks the grasp pixel (model.json's `grasp`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GraspRule {
    /// The paper's: the PositionNet's most probable pixel.
    #[default]
    Affordance,
    /// Beyond the paper: the PositionNet's probability times the JointNet's
    /// probability that the pixel is on a movable part (needs `files.joint`).
    AffordanceTimesMovable,
    /// Beyond the paper: [`Self::AffordanceTimesMovable`] times the grasp's
    /// worth for its lever arm about a hinge, as the JointNet reads it
    /// ([`crate::frame_joint::lever_weight`]; needs `files.joint`).
    AffordanceTimesMovableLever,
}

impl GraspRule {
    /// Every rule, in the order the docs list them.
    pub const ALL: [Self; 3] = [
        Self::Affordance,
        Self::AffordanceTimesMovable,
        Self::AffordanceTimesMovableLever,
    ];

    /// The name in model.json's `grasp` and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Affordance => "affordance",
            Self::AffordanceTimesMovable => "affordance_times_movable",
            Self::AffordanceTimesMovableLever => "affordance_times_movable_lever",
        }
    }

    /// Whether the rule reads the JointNet's fields.
    pub fn reads_joint(self) -> bool {
        self != Self::Affordance
    }

    /// Whether a package with (`has_joint`) or without a JointNet can pick
    /// its grasp by this rule; the reason when it cannot. The one statement
    /// of the rule that model.json, the policy and the CLI all check.
    pub fn check_joint(self, has_joint: bool) -> std::result::Result<(), String> {
        if self.reads_joint() && !has_joint {
            return Err(format!(
                "the `{}` grasp weights the grasp by the JointNet's fields, and the \
                 package names no JointNet (model.json `files.joint`; use `affordance`, or add \
                 one with `python -m umpnet_train.joint_net --export`)",
                self.name()
            ));
        }
        Ok(())
    }
}

impl std::str::FromStr for GraspRule {
    type Err = PolicyError;
    fn from_str(s: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|g| g.name() == s)
            .ok_or_else(|| {
                PolicyError::Input(format!(
                    "unknown grasp rule `{s}`; expected affordance, affordance_times_movable \
                     or affordance_times_movable_lever"
                ))
            })
    }
}

/// `model.json`.
#[derive(Clone, Debug, serde::Deserialize, serde::Serialize)]
pub struct ModelMeta {
    /// `umpnet-model`.
    pub format: String,
    /// The format's version ([`FORMAT_VERSION`]).
    pub version: u32,
    /// The method it was trained as.
    #[serde(default)]
    pub variant: Variant,
    /// The observation its networks take.
    pub input: InputSpec,
    /// Width of the encoder's embeddings.
    pub embedding: usize,
    /// The decoder's outputs.
    pub branches: Vec<Branch>,
    /// Whether the networks read the reference observation.
    pub uses_reference: bool,
    /// The network files.
    pub files: Files,
    /// The filter the runtime applies unless a caller overrides it.
    #[serde(default)]
    pub direction_filter: DirectionFilter,
    /// How the runtime picks the grasp pixel; the paper's rule when absent.
    #[serde(default)]
    pub grasp: GraspRule,
    /// The AoT class of each column of `aot_probs`: a permutation of -1, 0, +1
    /// (the exporter writes [-1, 0, 1]). The runtime reorders the columns to
    /// that canonical order, so packages of any class order mean the same.
    #[serde(default = "default_aot_classes")]
    pub aot_classes: Vec<i64>,
    /// SignedDist packages: a predicted |signed distance| at or below this
    /// means "no effective change" (AoT 0). The exporter writes half the
    /// smallest move its training labels count (those labels put 0 for no
    /// move and at least that move otherwise); packages without the field
    /// keep δ = 0.15.
    #[serde(default = "default_signed_distance_threshold")]
    pub signed_distance_threshold: f32,
    /// What made the package: command, seed, commit, epochs (free-form).
    #[serde(default)]
    pub provenance: serde_json::Value,
    /// Scores it was shipped with (free-form).
    #[serde(default)]
    pub evaluation: serde_json::Value,
}

fn default_aot_classes() -> Vec<i64> {
    vec![-1, 0, 1]
}

fn default_signed_distance_threshold() -> f32 {
    0.15
}

/// Which decoder outputs the package has, as the runtime uses them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Branches {
    /// Dist and AoT (UMPNet, SingleStep).
    DistAot,
    /// AoT only (the AoTOnly baseline).
    AotOnly,
    /// One signed distance (the SignedDist baseline).
    SignedDist,
    /// The probability that the action moves the object (the Where2Act-style baseline).
    Binary,
    /// No candidate scoring: the decoder regresses the direction that turns the
    /// current observation into the reference one (the Inverse baseline, goal task only).
    Inverse,
}

impl Branches {
    /// Packages that act only toward a goal observation (no exploration behaviour).
    pub fn goal_only(self) -> bool {
        self == Branches::Inverse
    }
}

impl ModelMeta {
    /// Reads `model.json` at `meta_path` and checks every field the runtime
    /// relies on before anything is allocated from it.
    pub fn read(meta_path: &Path) -> Result<ModelMeta> {
        // A few KB: a FIFO or device would block or never end, and a huge
        // file is not a model.json.
        match std::fs::metadata(meta_path) {
            Ok(m) if !m.is_file() => {
                return Err(pkg_err(
                    meta_path,
                    "not a regular file (a folder, FIFO or device)",
                ));
            }
            Ok(m) if m.len() > MAX_META_BYTES => {
                return Err(pkg_err(
                    meta_path,
                    format!(
                        "{} bytes; model.json is limited to {MAX_META_BYTES}",
                        m.len()
                    ),
                ));
            }
            _ => {}
        }
        let text = std::fs::read_to_string(meta_path)
            .map_err(|e| pkg_err(meta_path, format!("cannot read: {e}")))?;
        let meta: ModelMeta =
            serde_json::from_str(&text).map_err(|e| pkg_err(meta_path, format!("invalid: {e}")))?;
        meta.check(meta_path)?;
        Ok(meta)
    }

    fn check(&self, meta_path: &Path) -> Result<()> {
        let fail = |what: String| Err(pkg_err(meta_path, what));
        if self.format != "umpnet-model" {
            return fail(format!(
                "`format` is `{}`, expected `umpnet-model`",
                self.format
            ));
        }
        if self.version != FORMAT_VERSION {
            return fail(format!(
                "`version` is {}, this runtime reads version {FORMAT_VERSION}",
                self.version
            ));
        }
        if self.input.channels != CHANNELS {
            return fail(format!(
                "`input.channels` is {}, expected {CHANNELS}",
                self.input.channels
            ));
        }
        if self.input.height == 0 || self.input.width == 0 || self.embedding == 0 {
            return fail("`input.height`, `input.width` and `embedding` must be positive".into());
        }
        // Checked before any tensor of these sizes is made: a declared
        // 20000x20000 input would allocate 16 GB, u64::MAX would overflow.
        if self.input.height > MAX_SIDE || self.input.width > MAX_SIDE {
            return fail(format!(
                "`input` is {}x{}; each side is limited to {MAX_SIDE} (the paper's is 480x640)",
                self.input.height, self.input.width
            ));
        }
        if self.embedding > MAX_EMBEDDING {
            return fail(format!(
                "`embedding` is {}; limited to {MAX_EMBEDDING}",
                self.embedding
            ));
        }
        let mut classes = self.aot_classes.clone();
        classes.sort_unstable();
        if classes != [-1, 0, 1] {
            return fail(format!(
                "`aot_classes` is {:?}, expected an order of -1, 0 and 1 (e.g. [-1, 0, 1])",
                self.aot_classes
            ));
        }
        if !(self.signed_distance_threshold.is_finite() && self.signed_distance_threshold >= 0.0) {
            return fail(format!(
                "`signed_distance_threshold` is {}, expected a finite number >= 0",
                self.signed_distance_threshold
            ));
        }
        if let Err(why) = self.grasp.check_joint(self.files.joint.is_some()) {
            return fail(format!("`grasp`: {why}"));
        }
        self.decoder(meta_path).map(|_| ())
    }

    /// What the decoder computes, and the names of its outputs.
    pub fn decoder(&self, meta_path: &Path) -> Result<(Branches, Vec<String>)> {
        let has = |b: Branch| self.branches.contains(&b);
        let (branches, outputs): (Branches, &[&str]) = if has(Branch::Dist) && has(Branch::Aot) {
            (Branches::DistAot, &["distance", "aot_probs"])
        } else if has(Branch::Aot) {
            (Branches::AotOnly, &["aot_probs"])
        } else if has(Branch::SignedDist) {
            (Branches::SignedDist, &["signed_distance"])
        } else if has(Branch::Binary) {
            (Branches::Binary, &["success_prob"])
        } else if has(Branch::Inverse) {
            (Branches::Inverse, &["predicted_direction"])
        } else {
            return Err(pkg_err(
                meta_path,
                format!(
                    "`branches` {:?}: expected [dist, aot], [aot], [signed_dist], [binary] or [inverse]",
                    self.branches
                ),
            ));
        };
        Ok((branches, outputs.iter().map(|s| (*s).to_owned()).collect()))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;

    fn shipped() -> serde_json::Value {
        let path =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/umpnet-small/model.json");
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
    }

    fn check(json: serde_json::Value) -> std::result::Result<ModelMeta, String> {
        let path = Path::new("pkg/model.json");
        let meta: ModelMeta = serde_json::from_value(json).map_err(|e| e.to_string())?;
        meta.check(path).map_err(|e| e.to_string())?;
        Ok(meta)
    }

    #[test]
    fn the_closed_sets_parse_by_name_and_refuse_other_names_with_the_choices() {
        let meta = check(shipped()).unwrap();
        assert_eq!(meta.variant, Variant::Umpnet);
        assert_eq!(meta.branches, [Branch::Dist, Branch::Aot]);
        assert_eq!(meta.direction_filter, DirectionFilter::None);
        assert_eq!(meta.decoder(Path::new("m")).unwrap().0, Branches::DistAot);
        for (field, value, expect) in [
            (
                "variant",
                "umpnet-xl",
                "`umpnet`, `single-step`, `aot-only`",
            ),
            ("direction_filter", "prev45", "`none`, `normal90`, `prev90`"),
        ] {
            let mut json = shipped();
            json[field] = value.into();
            let e = check(json).unwrap_err();
            assert!(e.contains(value) && e.contains(expect), "{e}");
        }
        let mut json = shipped();
        json["branches"] = serde_json::json!(["dist", "flow"]);
        let e = check(json).unwrap_err();
        assert!(e.contains("`flow`") && e.contains("`signed_dist`"), "{e}");
        let mut json = shipped();
        json["branches"] = serde_json::json!(["dist"]);
        let e = check(json).unwrap_err();
        assert!(e.contains("expected [dist, aot], [aot]"), "{e}");
        // Every name round-trips, and the baselines' names are the exporter's.
        for (name, variant) in [
            ("where2act", Variant::Where2act),
            ("signed-dist", Variant::SignedDist),
        ] {
            let mut json = shipped();
            json["variant"] = name.into();
            assert_eq!(check(json).unwrap().variant, variant);
            assert_eq!(serde_json::to_value(variant).unwrap(), name);
        }
        for f in DirectionFilter::ALL {
            assert_eq!(serde_json::to_value(f).unwrap(), f.name());
        }
    }
}
