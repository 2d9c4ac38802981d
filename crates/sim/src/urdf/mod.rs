//! URDF loading: a mending pass over the raw XML (PartNet-Mobility quirks),
//! urdf-rs for the structure, then validation into an [`ObjectModel`].
//!
//! Errors name the file, the element (with its line) and what was expected.
//!
//! - `xml`: checks on the raw text and the mending pass;
//! - `checks`: the numbers and tensors urdf-rs parsed, before any is used;
//! - `build`: geometry, colours and the joint tree into an [`ObjectModel`].
mod build;
mod checks;
#[cfg(test)]
mod tests;
mod xml;

use crate::error::{Result, SimError};
use crate::mesh::TriMesh;
use std::collections::{HashMap, HashSet};
use std::path::Path;

// The model types live in `crate::model`; they are re-exported here because
// the loader is where most users meet them.
pub use crate::model::{
    JointKind, JointModel, LinkModel, MAX_COORDINATE, MAX_LIMIT, ObjectModel, VisualModel,
};

/// Limits on what a URDF may hold. PartNet-Mobility's files are far below
/// each (tens of KB, depth under 8, under 40 links); they bound the time and
/// memory a hostile file can take, and every one is an error naming the file.
pub const MAX_URDF_BYTES: u64 = 16 << 20;
/// Element nesting (a URDF needs about 6: robot, link, visual, geometry, mesh).
pub const MAX_XML_DEPTH: usize = 64;
/// Attributes on one element.
pub const MAX_ATTRIBUTES: usize = 64;
/// Links (and joints) of one object: the renderer's part slots.
pub const MAX_LINKS: usize = 64;
/// Longest number token (a numeric attribute's value is a few of these).
pub(crate) const MAX_NUMBER_TOKEN: usize = 64;
/// A link's mass (kg): a milligram to a thousand tonnes. Outside it the
/// solver's mass ratios (gripper against part) lose all precision in f32.
pub const MIN_MASS: f64 = 1e-6;
/// The largest link mass (kg), see [`MIN_MASS`].
pub const MAX_MASS: f64 = 1e6;
/// Mesh scales: beyond these a mesh is flat or huge in f32.
pub const MIN_MESH_SCALE: f64 = 1e-6;
/// The largest mesh scale, see [`MIN_MESH_SCALE`].
pub const MAX_MESH_SCALE: f64 = 1e6;
/// Longest attribute value quoted back in an error message.
pub(crate) const MAX_QUOTED: usize = 80;

/// Reads and validates a URDF file.
pub fn load_urdf(path: &Path) -> Result<ObjectModel> {
    if let Ok(meta) = std::fs::metadata(path)
        && meta.is_file()
        && meta.len() > MAX_URDF_BYTES
    {
        return Err(urdf_err(
            path,
            format!(
                "{} bytes; URDF files are limited to {MAX_URDF_BYTES}",
                meta.len()
            ),
        ));
    }
    let text = crate::fsio::read_text(path, MAX_URDF_BYTES)?;
    parse_urdf(&text, path)
}

pub(crate) fn urdf_err(file: &Path, what: impl Into<String>) -> SimError {
    SimError::Urdf {
        file: file.to_path_buf(),
        what: what.into(),
    }
}

/// Parses URDF text; `path` names the file in errors and anchors relative mesh paths.
pub fn parse_urdf(text: &str, path: &Path) -> Result<ObjectModel> {
    parse_urdf_with(text, path, &|_| None)
}

/// Supplies meshes by path before the disk is asked (in-memory generated objects).
pub type MeshSource<'a> = &'a dyn Fn(&Path) -> Option<TriMesh>;

/// As [`parse_urdf`], with meshes looked up in `meshes` first.
#[expect(
    clippy::too_many_lines,
    reason = "the loader's stages in order (size, XML, mending, checks, build), each a call"
)]
pub fn parse_urdf_with(text: &str, path: &Path, meshes: MeshSource<'_>) -> Result<ObjectModel> {
    if text.len() as u64 > MAX_URDF_BYTES {
        return Err(urdf_err(
            path,
            format!(
                "{} bytes; URDF files are limited to {MAX_URDF_BYTES}",
                text.len()
            ),
        ));
    }
    xml::check_xml_shape(text, path)?;
    xml::check_char_refs(text, path)?;
    let doc = roxmltree::Document::parse(text)
        .map_err(|e| urdf_err(path, format!("not well-formed XML: {e}")))?;
    let root = doc.root_element();
    for kind in ["link", "joint"] {
        let n = root.children().filter(|c| c.has_tag_name(kind)).count();
        if n > MAX_LINKS {
            return Err(urdf_err(
                path,
                format!("{n} <{kind}> elements; an object may have at most {MAX_LINKS}"),
            ));
        }
    }
    if root.tag_name().name() != "robot" {
        return Err(urdf_err(
            path,
            format!(
                "root element is <{}>, expected <robot>",
                root.tag_name().name()
            ),
        ));
    }
    let line_of = |n: roxmltree::Node<'_, '_>| doc.text_pos_at(n.range().start).row;
    // urdf-rs answers a <geometry> without a shape with a two-line reader dump.
    const SHAPES: &[&str] = &["box", "cylinder", "capsule", "sphere", "mesh"];
    for g in root.descendants().filter(|n| n.has_tag_name("geometry")) {
        let shapes = g.children().filter(|c| c.is_element()).count();
        if shapes != 1
            || !g
                .children()
                .filter(|c| c.is_element())
                .all(|c| SHAPES.contains(&c.tag_name().name()))
        {
            return Err(urdf_err(
                path,
                format!(
                    "<geometry> at line {} must hold exactly one of <box>, <cylinder>, <capsule>, <sphere>, <mesh>",
                    line_of(g)
                ),
            ));
        }
    }
    let mut mended = String::with_capacity(text.len() + 256);
    xml::mend(root, path, &line_of, &mut mended)?;
    let with_inertial: HashSet<String> = root
        .children()
        .filter(|n| n.has_tag_name("link") && n.children().any(|c| c.has_tag_name("inertial")))
        .filter_map(|n| n.attribute("name").map(str::to_owned))
        .collect();
    let mut joint_lines: HashMap<String, u32> = HashMap::new();
    for n in root.children().filter(|n| n.has_tag_name("joint")) {
        let name = n.attribute("name").unwrap_or_default();
        if let Some(first) = joint_lines.insert(name.to_owned(), line_of(n)) {
            return Err(urdf_err(
                path,
                format!(
                    "line {}: a second joint named `{}` (the first is at line {first}); joint names must be unique",
                    line_of(n),
                    quoted(name)
                ),
            ));
        }
        // The URDF spec requires <limit> on revolute and prismatic joints; without
        // one a reader's default locks the joint at 0 and nothing says why.
        let limited = matches!(n.attribute("type"), Some("revolute" | "prismatic"));
        let limit = n.children().find(|c| c.has_tag_name("limit"));
        if limited && limit.is_none() {
            return Err(urdf_err(
                path,
                format!(
                    "<joint name=\"{}\"> at line {}: a {} joint needs a <limit lower=.. upper=..> (the URDF spec requires one)",
                    quoted(name),
                    line_of(n),
                    n.attribute("type").unwrap_or_default()
                ),
            ));
        }
        // Both default to 0 in the spec, which locks the joint: a file that
        // leaves them out almost always meant a joint that moves.
        if let Some(limit) = limit.filter(|_| limited)
            && let Some(missing) = ["lower", "upper"]
                .into_iter()
                .find(|a| limit.attribute(*a).is_none())
        {
            return Err(urdf_err(
                path,
                format!(
                    "<joint name=\"{}\"> at line {}: its <limit> has no `{missing}`; give both lower and upper (left out, both are 0 and the joint cannot move), or make an unlimited hinge `continuous`",
                    quoted(name),
                    line_of(n)
                ),
            ));
        }
    }
    check_mimics(root, path, &line_of)?;
    let robot = urdf_rs::read_from_string(&mended)
        .map_err(|e| urdf_err(path, format!("invalid URDF: {e}")))?;
    checks::check_numbers(&robot, path)?;
    build::build_model(robot, path, &with_inertial, &joint_lines, meshes)
}

/// `value`, cut to a length a message can quote.
pub(crate) fn quoted(value: &str) -> String {
    match value.char_indices().nth(MAX_QUOTED) {
        Some((cut, _)) => format!("{}... ({} bytes)", &value[..cut], value.len()),
        None => value.to_owned(),
    }
}

/// `<mimic>` couples a joint to another. The simulator has no coupled
/// joints, so every `<mimic>` is refused, with what is wrong with it first
/// (a missing or unknown target, the joint itself, a multiplier or offset
/// that is no finite number, a cycle) and otherwise what to do instead:
/// ignoring it would let a part move that the file says must follow another.
fn check_mimics(
    root: roxmltree::Node<'_, '_>,
    path: &Path,
    line_of: &dyn Fn(roxmltree::Node<'_, '_>) -> u32,
) -> Result<()> {
    let joints: Vec<roxmltree::Node<'_, '_>> = root
        .children()
        .filter(|n| n.has_tag_name("joint"))
        .collect();
    let target_of = |name: &str| {
        joints
            .iter()
            .find(|j| j.attribute("name") == Some(name))
            .and_then(|j| j.children().find(|c| c.has_tag_name("mimic")))
            .and_then(|m| m.attribute("joint"))
    };
    for j in &joints {
        let Some(m) = j.children().find(|c| c.has_tag_name("mimic")) else {
            continue;
        };
        let name = j.attribute("name").unwrap_or_default();
        let at = format!("<joint name=\"{}\"> at line {}", quoted(name), line_of(m));
        let fail = |what: String| Err(urdf_err(path, format!("{at}: {what}")));
        let Some(target) = m.attribute("joint") else {
            return fail("<mimic> names no joint (its `joint` attribute is missing)".into());
        };
        if target == name {
            return fail("<mimic> names the joint itself".into());
        }
        if !joints.iter().any(|o| o.attribute("name") == Some(target)) {
            return fail(format!(
                "<mimic joint=\"{}\"> names a joint the file does not have",
                quoted(target)
            ));
        }
        for attr in ["multiplier", "offset"] {
            if let Some(v) = m.attribute(attr)
                && !v
                    .trim()
                    .parse::<f64>()
                    .is_ok_and(|x| (x as f32).is_finite())
            {
                return fail(format!(
                    "<mimic {attr}=\"{}\"> must be a finite number",
                    quoted(v)
                ));
            }
        }
        // Following the targets from here either ends or comes back.
        let mut seen = vec![name];
        let mut next = Some(target);
        while let Some(t) = next {
            if seen.contains(&t) {
                return fail(format!(
                    "<mimic> joints form a cycle: {} -> {}",
                    seen.iter()
                        .map(|s| quoted(s))
                        .collect::<Vec<_>>()
                        .join(" -> "),
                    quoted(t)
                ));
            }
            seen.push(t);
            next = target_of(t);
        }
        return fail(format!(
            "<mimic joint=\"{}\"> couples this joint to another, and umpnet simulates no coupled joints; remove the <mimic> element to let `{}` move on its own, or make the joint `fixed`",
            quoted(target),
            quoted(name)
        ));
    }
    Ok(())
}
