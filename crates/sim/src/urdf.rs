//! URDF loading: a mending pass over the raw XML (PartNet-Mobility quirks),
//! urdf-rs for the structure, then validation into an [`ObjectModel`].
//!
//! Errors name the file, the element (with its line) and what was expected.
use crate::error::{Result, SimError};
use crate::math::{Mat3, Pose3, Quat, Vec3};
use crate::mesh::TriMesh;
use std::collections::{HashMap, HashSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    Fixed,
    Revolute,
    Continuous,
    Prismatic,
}

impl JointKind {
    pub fn is_movable(self) -> bool {
        self != JointKind::Fixed
    }
    pub fn is_prismatic(self) -> bool {
        self == JointKind::Prismatic
    }
}

#[derive(Clone, Debug)]
pub struct VisualModel {
    /// Mesh in the link frame (origin and scale applied).
    pub mesh_in_link: TriMesh,
    pub color: [f32; 3],
}

#[derive(Clone, Debug)]
pub struct LinkModel {
    pub name: String,
    pub visuals: Vec<VisualModel>,
    pub mass: f32,
    pub com_in_link: Vec3,
    /// Inertia tensor about the centre of mass, in link axes.
    pub inertia_in_link: Mat3,
    /// True when the file gave no `<inertial>` and one was derived.
    pub inertial_derived: bool,
}

#[derive(Clone, Debug)]
pub struct JointModel {
    pub name: String,
    pub kind: JointKind,
    pub parent: usize,
    pub child: usize,
    /// Joint frame (= child frame at joint value 0) in the parent link frame.
    pub parent_from_joint: Pose3,
    /// Unit axis in the joint frame.
    pub axis_in_joint: Vec3,
    /// Limits; continuous joints have (-inf, inf).
    pub lower: f32,
    pub upper: f32,
    pub damping: f32,
    pub friction: f32,
}

/// A loaded, validated articulated object: a tree of links rooted at `root`.
#[derive(Clone, Debug)]
pub struct ObjectModel {
    pub source: PathBuf,
    pub name: String,
    pub links: Vec<LinkModel>,
    /// Joints ordered so that every parent link appears before its child.
    pub joints: Vec<JointModel>,
    pub root: usize,
}

impl ObjectModel {
    /// The object uniformly scaled by `scale`, as PyBullet's `globalScaling`
    /// does: geometry, joint origins, centres of mass and prismatic limits
    /// scale; masses keep their value and inertias scale with its square.
    pub fn scaled(mut self, scale: f32) -> Result<Self> {
        if !(scale.is_finite() && scale > 0.0 && scale <= 1000.0) {
            return Err(SimError::InvalidScene(format!(
                "object scale must be a number in (0, 1000], got {scale}"
            )));
        }
        if scale == 1.0 {
            return Ok(self);
        }
        for link in &mut self.links {
            for v in &mut link.visuals {
                for p in &mut v.mesh_in_link.positions {
                    *p *= scale;
                }
            }
            link.com_in_link *= scale;
            link.inertia_in_link *= scale * scale;
        }
        for joint in &mut self.joints {
            joint.parent_from_joint.translation *= scale;
            if joint.kind.is_prismatic() {
                joint.lower *= scale;
                joint.upper *= scale;
            }
        }
        Ok(self)
    }

    pub fn movable_joints(&self) -> impl Iterator<Item = (usize, &JointModel)> {
        self.joints
            .iter()
            .enumerate()
            .filter(|(_, j)| j.kind.is_movable())
    }
    pub fn joint_by_name(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }
    /// The joint whose child is `link`, if any.
    pub fn parent_joint_of(&self, link: usize) -> Option<usize> {
        self.joints.iter().position(|j| j.child == link)
    }
}

const NUMERIC_ATTRS: &[&str] = &[
    "xyz", "rpy", "lower", "upper", "effort", "velocity", "value", "ixx", "ixy", "ixz", "iyy",
    "iyz", "izz", "radius", "length", "size", "scale", "rgba", "damping", "friction",
];

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
const MAX_NUMBER_TOKEN: usize = 64;
/// Largest coordinate (m) of any origin or vertex in a link's frame.
pub const MAX_COORDINATE: f32 = 1000.0;
/// Joint limits, in metres (prismatic) or radians (revolute): a wider range
/// is a continuous joint written as a limited one, or a unit mistake.
pub const MAX_LIMIT: f64 = 1000.0;
/// Mesh scales: beyond these a mesh is flat or huge in f32.
pub const MIN_MESH_SCALE: f64 = 1e-6;
pub const MAX_MESH_SCALE: f64 = 1e6;
/// Longest attribute value quoted back in an error message.
const MAX_QUOTED: usize = 80;

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

fn urdf_err(file: &Path, what: impl Into<String>) -> SimError {
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
pub fn parse_urdf_with(text: &str, path: &Path, meshes: MeshSource) -> Result<ObjectModel> {
    if text.len() as u64 > MAX_URDF_BYTES {
        return Err(urdf_err(
            path,
            format!(
                "{} bytes; URDF files are limited to {MAX_URDF_BYTES}",
                text.len()
            ),
        ));
    }
    check_xml_shape(text, path)?;
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
    let line_of = |n: roxmltree::Node| doc.text_pos_at(n.range().start).row;
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
    mend(root, path, &line_of, &mut mended)?;
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
        if limited && !n.children().any(|c| c.has_tag_name("limit")) {
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
    }
    let robot = urdf_rs::read_from_string(&mended)
        .map_err(|e| urdf_err(path, format!("invalid URDF: {e}")))?;
    check_numbers(&robot, path)?;
    build_model(robot, path, &with_inertial, &joint_lines, meshes)
}

/// Nesting depth and attributes per element, checked on the raw text before
/// any XML reader sees it: deep nesting overflows recursive readers' stacks,
/// and thousands of attributes on one element make their duplicate checks
/// quadratic. Malformed markup is left to the XML reader's message.
fn check_xml_shape(text: &str, path: &Path) -> Result<()> {
    let b = text.as_bytes();
    let line = |at: usize| 1 + b.iter().take(at).filter(|c| **c == b'\n').count();
    let after = |from: usize, end: &[u8]| -> usize {
        b.get(from..)
            .unwrap_or_default()
            .windows(end.len())
            .position(|w| w == end)
            .map_or(b.len(), |k| from + k + end.len())
    };
    let (mut i, mut depth) = (0usize, 0usize);
    while let Some(off) = b.get(i..).and_then(|r| r.iter().position(|c| *c == b'<')) {
        let s = i + off;
        let rest = b.get(s..).unwrap_or_default();
        if rest.starts_with(b"<!--") {
            i = after(s, b"-->");
        } else if rest.starts_with(b"<![CDATA[") {
            i = after(s, b"]]>");
        } else if rest.starts_with(b"<?") {
            i = after(s, b"?>");
        } else if rest.starts_with(b"<!") {
            i = after(s, b">");
        } else if rest.starts_with(b"</") {
            depth = depth.saturating_sub(1);
            i = after(s, b">");
        } else {
            let (mut k, mut quote, mut attributes) = (s + 1, None, 0usize);
            while let Some(&c) = b.get(k) {
                match (quote, c) {
                    (Some(q), c) if c == q => quote = None,
                    (Some(_), _) => {}
                    (None, c @ (b'"' | b'\'')) => quote = Some(c),
                    (None, b'=') => attributes += 1,
                    (None, b'>') => break,
                    _ => {}
                }
                k += 1;
            }
            if attributes > MAX_ATTRIBUTES {
                return Err(urdf_err(
                    path,
                    format!(
                        "line {}: an element with {attributes} attributes; at most {MAX_ATTRIBUTES}",
                        line(s)
                    ),
                ));
            }
            if b.get(k.wrapping_sub(1)) != Some(&b'/') {
                depth += 1;
                if depth > MAX_XML_DEPTH {
                    return Err(urdf_err(
                        path,
                        format!(
                            "line {}: elements nested more than {MAX_XML_DEPTH} deep",
                            line(s)
                        ),
                    ));
                }
            }
            i = (k + 1).min(b.len());
        }
    }
    Ok(())
}

/// `value`, cut to a length a message can quote.
fn quoted(value: &str) -> String {
    match value.char_indices().nth(MAX_QUOTED) {
        Some((cut, _)) => format!("{}... ({} bytes)", &value[..cut], value.len()),
        None => value.to_owned(),
    }
}

/// Every number the model keeps must be finite: a NaN passes the XML reader
/// and poisons the physics silently (the joint comes back as NaN with exit 0).
/// They are checked as the f32 the physics stores: `1e39` is finite in the
/// file and infinite after conversion. Sizes, inertias and colours must also
/// be in range: a negative inertia freezes a joint, a negative size or scale
/// turns a mesh inside out.
fn check_numbers(robot: &urdf_rs::Robot, path: &Path) -> Result<()> {
    let finite = |v: f64| (v as f32).is_finite();
    let bad = |what: String, values: &[f64]| -> Result<()> {
        if values.iter().all(|v| finite(*v)) {
            Ok(())
        } else {
            Err(urdf_err(
                path,
                format!("{what} must be finite numbers within f32 range, found {values:?}"),
            ))
        }
    };
    let at_least = |what: String, values: &[f64], min: f64, strict: bool| -> Result<()> {
        bad(what.clone(), values)?;
        if values
            .iter()
            .all(|v| if strict { *v > min } else { *v >= min })
        {
            Ok(())
        } else {
            let rel = if strict { ">" } else { ">=" };
            Err(urdf_err(
                path,
                format!("{what} must be {rel} {min}, found {values:?}"),
            ))
        }
    };
    let origin = |what: String, o: &urdf_rs::Pose| -> Result<()> {
        bad(
            format!("{what} <origin xyz/rpy>"),
            &[o.xyz.0, o.rpy.0].concat(),
        )
    };
    let geometry = |what: String, g: &urdf_rs::Geometry| -> Result<()> {
        match g {
            urdf_rs::Geometry::Box { size } => {
                at_least(format!("{what} <box size>"), &size.0, 0.0, false)
            }
            urdf_rs::Geometry::Cylinder { radius, length }
            | urdf_rs::Geometry::Capsule { radius, length } => at_least(
                format!("{what} radius/length"),
                &[*radius, *length],
                0.0,
                false,
            ),
            urdf_rs::Geometry::Sphere { radius } => {
                at_least(format!("{what} <sphere radius>"), &[*radius], 0.0, false)
            }
            urdf_rs::Geometry::Mesh { scale, .. } => match scale {
                Some(s) => {
                    at_least(format!("{what} <mesh scale>"), &s.0, 0.0, true)?;
                    // 1e-300 is positive in the file and zero as f32: a flat mesh.
                    if s.0
                        .iter()
                        .all(|v| (MIN_MESH_SCALE..=MAX_MESH_SCALE).contains(v))
                    {
                        Ok(())
                    } else {
                        Err(urdf_err(
                            path,
                            format!(
                                "{what} <mesh scale> must be within [{MIN_MESH_SCALE:e}, {MAX_MESH_SCALE:e}], found {:?}",
                                s.0
                            ),
                        ))
                    }
                }
                None => Ok(()),
            },
        }
    };
    let color = |what: String, m: &Option<urdf_rs::Material>| -> Result<()> {
        match m.as_ref().and_then(|m| m.color.as_ref()) {
            Some(c) if !c.rgba.0.iter().all(|v| (0.0..=1.0).contains(v)) => Err(urdf_err(
                path,
                format!(
                    "{what} <color rgba> must be 4 numbers in [0, 1], found {:?}",
                    c.rgba.0
                ),
            )),
            _ => Ok(()),
        }
    };
    for m in &robot.materials {
        color(format!("material `{}`", m.name), &Some(m.clone()))?;
    }
    for l in &robot.links {
        let i = &l.inertial;
        origin(format!("link `{}` <inertial>", l.name), &i.origin)?;
        let t = &i.inertia;
        bad(
            format!("link `{}` <inertia>", l.name),
            &[t.ixx, t.ixy, t.ixz, t.iyy, t.iyz, t.izz],
        )?;
        at_least(
            format!("link `{}` <inertia> ixx/iyy/izz", l.name),
            &[t.ixx, t.iyy, t.izz],
            0.0,
            false,
        )?;
        // A body's inertia tensor has non-negative principal moments that obey the
        // triangle inequality (i1 + i2 - i3 = 2 * integral of r3^2 dm >= 0); one
        // that breaks either is no rigid body, and the solver turns it into NaN.
        let moments = principal_moments([
            [t.ixx, t.ixy, t.ixz],
            [t.ixy, t.iyy, t.iyz],
            [t.ixz, t.iyz, t.izz],
        ]);
        let [a, b, c] = moments;
        let slack = 1e-6 * (a.abs() + b.abs() + c.abs());
        if !moments.iter().all(|m| m.is_finite() && *m >= -slack)
            || a + b < c - slack
            || b + c < a - slack
            || a + c < b - slack
        {
            return Err(urdf_err(
                path,
                format!(
                    "link `{}` <inertia> has principal moments {moments:?}: they must be non-negative, each at most the sum of the other two, or no rigid body has them",
                    l.name
                ),
            ));
        }
        for v in &l.visual {
            let what = format!("link `{}` <visual>", l.name);
            origin(what.clone(), &v.origin)?;
            geometry(what.clone(), &v.geometry)?;
            color(what, &v.material)?;
        }
        for c in &l.collision {
            let what = format!("link `{}` <collision>", l.name);
            origin(what.clone(), &c.origin)?;
            geometry(what, &c.geometry)?;
        }
    }
    for j in &robot.joints {
        origin(format!("joint `{}`", j.name), &j.origin)?;
        // Checked before normalising: `1e39 0 0` is a direction in f64 but
        // overflows the f32 the file's numbers are meant as.
        bad(format!("joint `{}` <axis xyz>", j.name), &j.axis.xyz.0)?;
        let l = &j.limit;
        bad(
            format!("joint `{}` <limit> lower/upper", j.name),
            &[l.lower, l.upper],
        )?;
        let limited = matches!(
            j.joint_type,
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Prismatic
        );
        if limited && (l.lower.abs() > MAX_LIMIT || l.upper.abs() > MAX_LIMIT) {
            return Err(urdf_err(
                path,
                format!(
                    "joint `{}` <limit> lower/upper must be within ±{MAX_LIMIT} (m or rad), found lower={} upper={}; a joint without limits is `continuous`",
                    j.name, l.lower, l.upper
                ),
            ));
        }
        at_least(
            format!("joint `{}` <limit> effort/velocity", j.name),
            &[l.effort, l.velocity],
            0.0,
            false,
        )?;
    }
    Ok(())
}

/// Eigenvalues of a symmetric 3x3 matrix (closed form, Smith 1961).
fn principal_moments(m: [[f64; 3]; 3]) -> [f64; 3] {
    let [[a, d, e], [_, b, f], [_, _, c]] = m;
    let off = d * d + e * e + f * f;
    if off == 0.0 {
        return [a, b, c];
    }
    let q = (a + b + c) / 3.0;
    let p = (((a - q).powi(2) + (b - q).powi(2) + (c - q).powi(2) + 2.0 * off) / 6.0).sqrt();
    if !(p.is_finite() && p > 0.0) {
        return [f64::NAN; 3];
    }
    let n = |x: f64| x / p;
    let (a2, b2, c2, d2, e2, f2) = (n(a - q), n(b - q), n(c - q), n(d), n(e), n(f));
    let det = a2 * (b2 * c2 - f2 * f2) - d2 * (d2 * c2 - f2 * e2) + e2 * (d2 * f2 - b2 * e2);
    let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
    let third = 2.0 * std::f64::consts::PI / 3.0;
    let l1 = q + 2.0 * p * phi.cos();
    let l3 = q + 2.0 * p * (phi + third).cos();
    [l1, 3.0 * q - l1 - l3, l3]
}

/// Writes the element back out as XML, fixing what PartNet-Mobility files get
/// wrong: `<limit>` without velocity/effort and stray characters in numbers.
fn mend(
    node: roxmltree::Node,
    path: &Path,
    line_of: &dyn Fn(roxmltree::Node) -> u32,
    out: &mut String,
) -> Result<()> {
    let name = node.tag_name().name();
    let _ = write!(out, "<{name}");
    for a in node.attributes() {
        let value = if NUMERIC_ATTRS.contains(&a.name())
            && !(name == "material" || name == "link" || name == "joint")
        {
            mend_numbers(a.value()).ok_or_else(|| {
                urdf_err(
                    path,
                    format!(
                        "<{name}> at line {}: attribute {}=\"{}\" is not a list of numbers",
                        line_of(node),
                        a.name(),
                        quoted(a.value())
                    ),
                )
            })?
        } else {
            a.value().to_owned()
        };
        let _ = write!(out, " {}=\"{}\"", a.name(), escape(&value));
    }
    if name == "limit" {
        for (attr, default) in [("velocity", "1.0"), ("effort", "100.0")] {
            if node.attribute(attr).is_none() {
                let _ = write!(out, " {attr}=\"{default}\"");
            }
        }
    }
    out.push('>');
    for child in node.children() {
        if child.is_element() {
            mend(child, path, line_of, out)?;
        } else if let Some(t) = child.text() {
            out.push_str(&escape(t));
        }
    }
    let _ = write!(out, "</{name}>");
    Ok(())
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('"', "&quot;")
}

/// Keeps each whitespace-separated token that is a number, or the longest
/// numeric prefix of one with stray characters (`0.5,` -> `0.5`).
fn mend_numbers(value: &str) -> Option<String> {
    let mut parts = Vec::new();
    for tok in value
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|t| !t.is_empty())
    {
        if tok.len() > MAX_NUMBER_TOKEN {
            return None;
        }
        if tok.parse::<f64>().is_ok() {
            parts.push(tok.to_owned());
            continue;
        }
        let prefix = (1..tok.len())
            .rev()
            .filter(|&k| tok.is_char_boundary(k))
            .map(|k| &tok[..k])
            .find(|p| p.parse::<f64>().is_ok())?;
        parts.push(prefix.to_owned());
    }
    (!parts.is_empty()).then(|| parts.join(" "))
}

fn pose_of(p: &urdf_rs::Pose) -> Pose3 {
    let [x, y, z] = p.xyz.0.map(|v| v as f32);
    let [r, pi, yaw] = p.rpy.0.map(|v| v as f32);
    Pose3::from_parts(
        Vec3::new(x, y, z),
        Quat::from_euler(glam_euler_zyx(), yaw, pi, r),
    )
}

fn glam_euler_zyx() -> rapier3d::glamx::EulerRot {
    rapier3d::glamx::EulerRot::ZYX
}

fn geometry_mesh(
    g: &urdf_rs::Geometry,
    base_dir: &Path,
    file: &Path,
    link: &str,
    meshes: MeshSource,
) -> Result<TriMesh> {
    Ok(match g {
        urdf_rs::Geometry::Box { size } => TriMesh::cuboid(Vec3::from(size.0.map(|v| v as f32))),
        urdf_rs::Geometry::Cylinder { radius, length } => {
            TriMesh::cylinder(*radius as f32, *length as f32, 24)
        }
        urdf_rs::Geometry::Capsule { radius, length } => {
            TriMesh::cylinder(*radius as f32, *length as f32 + 2.0 * *radius as f32, 24)
        }
        urdf_rs::Geometry::Sphere { radius } => TriMesh::sphere(*radius as f32, 12, 24),
        urdf_rs::Geometry::Mesh { filename, scale } => {
            let mesh_path = mesh_path_in(base_dir, filename).ok_or_else(|| {
                urdf_err(
                    file,
                    format!(
                        "link `{link}`: mesh path `{}` leaves the object's folder (by its name or through a symbolic link); mesh paths must be relative and inside it",
                        quoted(filename)
                    ),
                )
            })?;
            let ext = mesh_path
                .extension()
                .and_then(|e| e.to_str())
                .unwrap_or("")
                .to_ascii_lowercase();
            if let Some(mesh) = meshes(&mesh_path) {
                return Ok(match scale {
                    Some(s) => mesh.scaled(Vec3::from(s.0.map(|v| v as f32))),
                    None => mesh,
                });
            }
            if ext != "obj" {
                return Err(urdf_err(
                    file,
                    format!(
                        "link `{link}`: mesh {} is not a Wavefront .obj file (the only mesh format supported)",
                        mesh_path.display()
                    ),
                ));
            }
            if !mesh_path.is_file() {
                return Err(urdf_err(
                    file,
                    format!("link `{link}`: mesh file {} not found", mesh_path.display()),
                ));
            }
            let mesh = TriMesh::read_obj(&mesh_path)?;
            match scale {
                Some(s) => mesh.scaled(Vec3::from(s.0.map(|v| v as f32))),
                None => mesh,
            }
        }
    })
}

/// A mesh visual's colour from its OBJ's MTL file, as the paper's code loads
/// PartNet-Mobility (PyBullet's `URDF_USE_MATERIAL_COLORS_FROM_MTL`): it takes
/// precedence over the URDF's colour.
fn mtl_color(g: &urdf_rs::Geometry, base_dir: &Path) -> Option<[f32; 3]> {
    let urdf_rs::Geometry::Mesh { filename, .. } = g else {
        return None;
    };
    TriMesh::obj_material_color(&mesh_path_in(base_dir, filename)?)
}

/// Where a mesh reference points, or None when it would leave the object's
/// folder (an absolute path, `..` above it, or a symbolic link whose target
/// is outside it): an object file must not make the loader read arbitrary
/// files.
fn mesh_path_in(base_dir: &Path, filename: &str) -> Option<PathBuf> {
    use std::path::Component;
    let rel = Path::new(
        filename
            .trim_start_matches("package://")
            .trim_start_matches("file://"),
    );
    let mut depth = 0usize;
    for c in rel.components() {
        match c {
            Component::Normal(_) => depth += 1,
            Component::CurDir => {}
            Component::ParentDir => depth = depth.checked_sub(1)?,
            Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    let path = base_dir.join(rel);
    // A symbolic link inside the folder may still point out of it: where the
    // file really is must be inside the folder too.
    match (path.canonicalize(), base_dir.canonicalize()) {
        (Ok(real), Ok(base)) if !real.starts_with(&base) => None,
        _ => Some(path),
    }
}

fn material_color(m: &Option<urdf_rs::Material>, named: &HashMap<String, [f32; 3]>) -> [f32; 3] {
    const DEFAULT: [f32; 3] = [0.7, 0.7, 0.7];
    match m {
        Some(m) => match &m.color {
            Some(c) => [c.rgba.0[0] as f32, c.rgba.0[1] as f32, c.rgba.0[2] as f32],
            None => named.get(&m.name).copied().unwrap_or(DEFAULT),
        },
        None => DEFAULT,
    }
}

fn build_model(
    robot: urdf_rs::Robot,
    path: &Path,
    with_inertial: &HashSet<String>,
    joint_lines: &HashMap<String, u32>,
    meshes: MeshSource,
) -> Result<ObjectModel> {
    let base_dir = path.parent().unwrap_or(Path::new("."));
    if robot.links.is_empty() {
        return Err(urdf_err(path, "no <link> elements"));
    }
    let named_colors: HashMap<String, [f32; 3]> = robot
        .materials
        .iter()
        .filter_map(|m| {
            m.color.as_ref().map(|c| {
                (
                    m.name.clone(),
                    [c.rgba.0[0] as f32, c.rgba.0[1] as f32, c.rgba.0[2] as f32],
                )
            })
        })
        .collect();
    let mut link_index = HashMap::new();
    let mut links = Vec::with_capacity(robot.links.len());
    let mut total_triangles = 0usize;
    for (i, l) in robot.links.iter().enumerate() {
        if link_index.insert(l.name.clone(), i).is_some() {
            return Err(urdf_err(path, format!("two links are named `{}`", l.name)));
        }
        let mut visuals = Vec::new();
        for v in &l.visual {
            let mesh = geometry_mesh(&v.geometry, base_dir, path, &l.name, meshes)?
                .transformed(&pose_of(&v.origin));
            total_triangles = total_triangles.saturating_add(mesh.triangles.len());
            if total_triangles > crate::mesh::MAX_TOTAL_TRIANGLES {
                return Err(urdf_err(
                    path,
                    format!(
                        "link `{}`: the object's visuals hold more than {} triangles in all \
                         (each use of a mesh counts); simplify the meshes",
                        l.name,
                        crate::mesh::MAX_TOTAL_TRIANGLES
                    ),
                ));
            }
            visuals.push(VisualModel {
                mesh_in_link: mesh,
                color: mtl_color(&v.geometry, base_dir)
                    .unwrap_or_else(|| material_color(&v.material, &named_colors)),
            });
        }
        let (mass, com, inertia, derived) = if with_inertial.contains(&l.name) {
            let i = &l.inertial;
            let m = i.mass.value as f32;
            if !(m.is_finite() && m > 0.0) {
                return Err(urdf_err(
                    path,
                    format!(
                        "link `{}`: <mass value> must be a positive number, found {}",
                        l.name, i.mass.value
                    ),
                ));
            }
            let t = &i.inertia;
            let local = Mat3::from_cols_array(&[
                t.ixx as f32,
                t.ixy as f32,
                t.ixz as f32,
                t.ixy as f32,
                t.iyy as f32,
                t.iyz as f32,
                t.ixz as f32,
                t.iyz as f32,
                t.izz as f32,
            ]);
            let frame = pose_of(&i.origin);
            let r = Mat3::from_quat(frame.rotation);
            (m, frame.translation, r * local * r.transpose(), false)
        } else {
            // PartNet-Mobility links carry no <inertial>. As PyBullet does: mass 1,
            // the centre of mass at the link origin, and the inertia of a solid
            // box the size of the collision (else visual) bounds.
            let mut shape = TriMesh::default();
            for c in &l.collision {
                shape.append(
                    &geometry_mesh(&c.geometry, base_dir, path, &l.name, meshes)?
                        .transformed(&pose_of(&c.origin)),
                );
            }
            if shape.positions.is_empty() {
                for v in &visuals {
                    shape.append(&v.mesh_in_link);
                }
            }
            let (lo, hi) = shape
                .bounds()
                .unwrap_or((Vec3::splat(-0.05), Vec3::splat(0.05)));
            let s = (hi - lo).max(Vec3::splat(0.01));
            let m = 1.0f32;
            let d = Vec3::new(
                s.y * s.y + s.z * s.z,
                s.x * s.x + s.z * s.z,
                s.x * s.x + s.y * s.y,
            ) * (m / 12.0);
            (m, Vec3::ZERO, Mat3::from_diagonal(d), true)
        };
        links.push(LinkModel {
            name: l.name.clone(),
            visuals,
            mass,
            com_in_link: com,
            inertia_in_link: inertia,
            inertial_derived: derived,
        });
    }

    let mut joints = Vec::with_capacity(robot.joints.len());
    let mut parent_of: HashMap<usize, String> = HashMap::new();
    for j in &robot.joints {
        let at = joint_lines
            .get(&j.name)
            .map(|l| format!(" at line {l}"))
            .unwrap_or_default();
        let jerr =
            |what: String| urdf_err(path, format!("<joint name=\"{}\">{at}: {what}", j.name));
        let kind = match &j.joint_type {
            urdf_rs::JointType::Fixed => JointKind::Fixed,
            urdf_rs::JointType::Revolute => JointKind::Revolute,
            urdf_rs::JointType::Continuous => JointKind::Continuous,
            urdf_rs::JointType::Prismatic => JointKind::Prismatic,
            other => {
                return Err(jerr(format!(
                    "joint type {other:?} is not supported (expected fixed, revolute, continuous or prismatic)"
                )));
            }
        };
        let parent = *link_index
            .get(&j.parent.link)
            .ok_or_else(|| jerr(format!("parent link `{}` does not exist", j.parent.link)))?;
        let child = *link_index
            .get(&j.child.link)
            .ok_or_else(|| jerr(format!("child link `{}` does not exist", j.child.link)))?;
        if let Some(other) = parent_of.insert(child, j.name.clone()) {
            return Err(jerr(format!(
                "link `{}` is already the child of joint `{other}`: kinematic loop (a URDF must be a tree)",
                j.child.link
            )));
        }
        // Normalised in f64: `1e30 0 0` is a valid direction whose f32 length overflows.
        let norm = j.axis.xyz.0.iter().map(|v| v * v).sum::<f64>().sqrt();
        let axis = Vec3::from(j.axis.xyz.0.map(|v| (v / norm) as f32));
        if kind.is_movable() && !(norm.is_finite() && norm > 1e-6 && axis.is_finite()) {
            return Err(jerr(format!(
                "<axis xyz> must be a non-zero finite vector, found {:?}",
                j.axis.xyz.0
            )));
        }
        let (lower, upper) = match kind {
            JointKind::Revolute | JointKind::Prismatic => {
                let (lo, hi) = (j.limit.lower, j.limit.upper);
                if !lo.is_finite() || !hi.is_finite() {
                    return Err(jerr(format!(
                        "<limit> lower/upper must be finite numbers, found lower={lo:?} upper={hi:?}"
                    )));
                }
                if lo > hi {
                    return Err(jerr(format!(
                        "<limit> lower ({lo:?}) is greater than upper ({hi:?})"
                    )));
                }
                (lo as f32, hi as f32)
            }
            JointKind::Continuous => (f32::NEG_INFINITY, f32::INFINITY),
            JointKind::Fixed => (0.0, 0.0),
        };
        let (damping, friction) = j
            .dynamics
            .as_ref()
            .map(|d| (d.damping as f32, d.friction as f32))
            .unwrap_or((0.0, 0.0));
        if !(damping.is_finite() && damping >= 0.0 && friction.is_finite() && friction >= 0.0) {
            return Err(jerr(format!(
                "<dynamics> damping/friction must be non-negative numbers, found {damping}/{friction}"
            )));
        }
        joints.push(JointModel {
            name: j.name.clone(),
            kind,
            parent,
            child,
            parent_from_joint: pose_of(&j.origin),
            axis_in_joint: if kind.is_movable() { axis } else { Vec3::X },
            lower,
            upper,
            damping,
            friction,
        });
    }
    let roots: Vec<usize> = (0..links.len())
        .filter(|i| !parent_of.contains_key(i))
        .collect();
    let root = match roots.as_slice() {
        [r] => *r,
        [] => {
            return Err(urdf_err(
                path,
                "every link has a parent joint: kinematic loop, no root link",
            ));
        }
        many => {
            let names: Vec<&str> = many
                .iter()
                .filter_map(|&i| links.get(i).map(|l| l.name.as_str()))
                .collect();
            return Err(urdf_err(
                path,
                format!(
                    "links {names:?} have no parent joint: expected one connected tree with a single root"
                ),
            ));
        }
    };
    // Order joints root-first; a joint left unordered sits on a cycle detached from the root.
    let mut ordered = Vec::with_capacity(joints.len());
    let mut reached: Vec<bool> = (0..links.len()).map(|l| l == root).collect();
    let mut frontier = vec![root];
    while let Some(l) = frontier.pop() {
        for j in joints.iter().filter(|j| j.parent == l) {
            if let Some(r) = reached.get_mut(j.child) {
                *r = true;
            }
            frontier.push(j.child);
            ordered.push(j.clone());
        }
    }
    if let Some(i) = reached.iter().position(|r| !r) {
        let name = |i: usize| links.get(i).map_or("?", |l| l.name.as_str());
        return Err(urdf_err(
            path,
            format!(
                "link `{}` is not connected to the root `{}`: kinematic loop",
                name(i),
                name(root)
            ),
        ));
    }
    // f32 physics resolves millimetres only within about a kilometre of the
    // origin; farther, joint limits and contacts stop holding.
    let far = |p: Vec3| p.abs().max_element() > MAX_COORDINATE;
    for l in &links {
        if far(l.com_in_link)
            || l.visuals
                .iter()
                .any(|v| v.mesh_in_link.positions.iter().any(|p| far(*p)))
        {
            return Err(urdf_err(
                path,
                format!(
                    "link `{}` reaches beyond {MAX_COORDINATE} m from its frame; objects must fit within that",
                    l.name
                ),
            ));
        }
    }
    if let Some(j) = joints.iter().find(|j| far(j.parent_from_joint.translation)) {
        return Err(urdf_err(
            path,
            format!(
                "joint `{}` <origin> is {:?}, beyond {MAX_COORDINATE} m; objects must fit within that",
                j.name, j.parent_from_joint.translation
            ),
        ));
    }
    Ok(ObjectModel {
        source: path.to_path_buf(),
        name: robot.name,
        links,
        joints: ordered,
        root,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn principal_moments_are_the_eigenvalues() {
        let mut m = principal_moments([[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 5.0]]);
        m.sort_by(f64::total_cmp);
        for (got, want) in m.iter().zip([1.0, 3.0, 5.0]) {
            assert!((got - want).abs() < 1e-9, "{m:?}");
        }
        assert_eq!(
            principal_moments([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]),
            [1.0, 2.0, 3.0]
        );
        let m = principal_moments([[0.2, 1e30, 0.0], [1e30, 0.3, 0.0], [0.0, 0.0, 0.1]]);
        assert!(m.iter().any(|v| *v < 0.0), "{m:?}");
    }

    fn wrap(body: &str) -> String {
        format!("<?xml version=\"1.0\"?><robot name=\"t\">{body}</robot>")
    }
    const BASE: &str = r#"<link name="base"><visual><geometry><box size="1 1 1"/></geometry></visual></link>
<link name="door"><visual><geometry><box size="0.1 1 1"/></geometry></visual></link>"#;

    fn err_of(body: &str) -> String {
        parse_urdf(&wrap(body), Path::new("obj/mobility.urdf"))
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn mesh_colours_come_from_the_mtl_file_as_pybullet_loads_partnet() {
        let dir = tempfile::tempdir().unwrap();
        let objs = dir.path().join("textured_objs");
        std::fs::create_dir_all(&objs).unwrap();
        std::fs::write(
            objs.join("part.obj"),
            "mtllib part.mtl\nusemtl paint\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        )
        .unwrap();
        std::fs::write(
            objs.join("part.mtl"),
            "newmtl other\nKd 0 0 1\nnewmtl paint\nKa 1 1 1\nKd 0.8 0.2 0.1\n",
        )
        .unwrap();
        std::fs::write(
            objs.join("plain.obj"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        )
        .unwrap();
        let urdf = dir.path().join("mobility.urdf");
        std::fs::write(
            &urdf,
            wrap(
                r#"<link name="base">
                 <visual><geometry><mesh filename="textured_objs/part.obj"/></geometry>
                   <material name="m"><color rgba="0 1 0 1"/></material></visual>
                 <visual><geometry><mesh filename="textured_objs/plain.obj"/></geometry>
                   <material name="m2"><color rgba="0 1 0 1"/></material></visual>
               </link>"#,
            ),
        )
        .unwrap();
        let m = load_urdf(&urdf).unwrap();
        assert_eq!(m.links[0].visuals[0].color, [0.8, 0.2, 0.1]);
        // No material in the OBJ: the URDF's colour.
        assert_eq!(m.links[0].visuals[1].color, [0.0, 1.0, 0.0]);
    }

    #[test]
    fn partnet_limit_without_velocity_and_stray_chars_load() {
        let m = parse_urdf(
            &wrap(&format!(
                r#"{BASE}<joint name="j" type="revolute"><origin xyz="0 0 0,"/><axis xyz="0 0 1"/>
                <parent link="base"/><child link="door"/><limit lower="0" upper="1.57x"/></joint>"#
            )),
            Path::new("m.urdf"),
        )
        .unwrap();
        assert_eq!(m.joints.len(), 1);
        assert!((m.joints[0].upper - 1.57).abs() < 1e-6);
        assert!(m.links[1].inertial_derived);
        assert_eq!(m.links[1].mass, 1.0);
    }

    #[test]
    fn errors_name_file_element_and_expectation() {
        assert!(err_of("<link name=\"a\"").starts_with("obj/mobility.urdf: not well-formed XML"));
        let e = err_of(&format!(
            r#"{BASE}<joint name="j" type="revolute"><parent link="base"/><child link="lid"/><axis xyz="0 0 1"/><limit lower="0" upper="1"/></joint>"#
        ));
        assert!(
            e.contains("<joint name=\"j\"> at line")
                && e.contains("child link `lid` does not exist"),
            "{e}"
        );
        let e = err_of(&format!(
            r#"{BASE}<joint name="j" type="prismatic"><parent link="base"/><child link="door"/><axis xyz="1 0 0"/><limit lower="NaN" upper="1"/></joint>"#
        ));
        assert!(e.contains("must be finite"), "{e}");
        let e = err_of(&format!(
            r#"{BASE}<joint name="j" type="prismatic"><parent link="base"/><child link="door"/><axis xyz="1 0 0"/><limit lower="2" upper="1"/></joint>"#
        ));
        assert!(e.contains("lower (2.0) is greater than upper (1.0)"), "{e}");
        let e = err_of(&format!(
            r#"{BASE}<joint name="a" type="fixed"><parent link="base"/><child link="door"/></joint>
               <joint name="b" type="fixed"><parent link="door"/><child link="base"/></joint>"#
        ));
        assert!(e.contains("kinematic loop"), "{e}");
        let e = err_of(
            r#"<link name="a"><visual><geometry><mesh filename="textured_objs/x.obj"/></geometry></visual></link>"#,
        );
        assert!(
            e.contains("mesh file obj/textured_objs/x.obj not found"),
            "{e}"
        );
        let e = err_of(&format!(
            r#"{BASE}<joint name="j" type="revolute"><parent link="base"/><child link="door"/><axis xyz="0 0 0"/><limit lower="0" upper="1"/></joint>"#
        ));
        assert!(e.contains("non-zero"), "{e}");
        let e = err_of(&format!(
            r#"{BASE}<joint name="j" type="floating"><parent link="base"/><child link="door"/></joint>"#
        ));
        assert!(e.contains("not supported"), "{e}");
    }

    #[test]
    fn numbers_that_overflow_or_underflow_f32_or_mean_nothing_are_named() {
        let joint = |axis: &str, limit: &str| {
            format!(
                r#"{BASE}<joint name="j" type="revolute"><parent link="base"/><child link="door"/><axis xyz="{axis}"/>{limit}</joint>"#
            )
        };
        let e = err_of(&joint("1e39 0 0", r#"<limit lower="0" upper="1"/>"#));
        assert!(
            e.contains("joint `j` <axis xyz> must be finite numbers within f32 range"),
            "{e}"
        );
        let e = err_of(&joint("1 0 0", r#"<limit lower="-1e30" upper="1e30"/>"#));
        assert!(
            e.contains("joint `j` <limit> lower/upper must be within ±1000"),
            "{e}"
        );
        let e = err_of(&joint("1 0 0", r#"<limit lower="0" upper="1001"/>"#));
        assert!(e.contains("<limit> lower/upper must be within"), "{e}");
        // The edge itself loads.
        assert!(
            parse_urdf(
                &wrap(&joint("1 0 0", r#"<limit lower="-1000" upper="1000"/>"#)),
                Path::new("x.urdf")
            )
            .is_ok()
        );
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("m.obj"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        )
        .unwrap();
        let mesh = |scale: &str| {
            wrap(&format!(
                r#"<link name="base"><visual><geometry><mesh filename="m.obj" scale="{scale}"/></geometry></visual></link>"#
            ))
        };
        let urdf = dir.path().join("mobility.urdf");
        for bad in ["1e-300 1 1", "1 1 1e7"] {
            let e = parse_urdf(&mesh(bad), &urdf).unwrap_err().to_string();
            assert!(
                e.contains("link `base` <visual> <mesh scale> must be within [1e-6, 1e6]"),
                "{bad}: {e}"
            );
        }
        assert!(parse_urdf(&mesh("1e-6 1 1e6"), &urdf).is_ok());
    }

    #[cfg(unix)]
    #[test]
    fn a_mesh_reached_through_a_link_to_outside_the_folder_is_refused() {
        let outside = tempfile::tempdir().unwrap();
        std::fs::write(
            outside.path().join("secret.obj"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        )
        .unwrap();
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("textured_objs")).unwrap();
        std::os::unix::fs::symlink(
            outside.path().join("secret.obj"),
            dir.path().join("textured_objs/m.obj"),
        )
        .unwrap();
        // A linked folder is the same case.
        std::os::unix::fs::symlink(outside.path(), dir.path().join("elsewhere")).unwrap();
        let urdf = dir.path().join("mobility.urdf");
        for name in ["textured_objs/m.obj", "elsewhere/secret.obj"] {
            let text = wrap(&format!(
                r#"<link name="base"><visual><geometry><mesh filename="{name}"/></geometry></visual></link>"#
            ));
            let e = parse_urdf(&text, &urdf).unwrap_err().to_string();
            assert!(e.contains("through a symbolic link"), "{name}: {e}");
        }
        // A link that stays inside the folder is fine.
        std::fs::copy(
            outside.path().join("secret.obj"),
            dir.path().join("real.obj"),
        )
        .unwrap();
        std::os::unix::fs::symlink(dir.path().join("real.obj"), dir.path().join("alias.obj"))
            .unwrap();
        let text = wrap(
            r#"<link name="base"><visual><geometry><mesh filename="alias.obj"/></geometry></visual></link>"#,
        );
        assert!(parse_urdf(&text, &urdf).is_ok());
    }

    #[test]
    fn the_total_of_all_visuals_is_capped_even_when_they_reuse_one_mesh() {
        use std::fmt::Write as _;
        let dir = tempfile::tempdir().unwrap();
        // A fan of 250,000 triangles; eight uses are the cap, nine are over it.
        let n = 250_000;
        let mut obj = String::new();
        for k in 0..n + 2 {
            let _ = writeln!(obj, "v {} {} 0", k as f32 * 1e-6, (k % 2) as f32 * 1e-3);
        }
        for k in 0..n {
            let _ = writeln!(obj, "f 1 {} {}", k + 2, k + 3);
        }
        std::fs::write(dir.path().join("big.obj"), obj).unwrap();
        let urdf = dir.path().join("mobility.urdf");
        let uses = |k: usize| {
            let visual = r#"<visual><geometry><mesh filename="big.obj"/></geometry></visual>"#;
            wrap(&format!(r#"<link name="base">{}</link>"#, visual.repeat(k)))
        };
        assert!(parse_urdf(&uses(8), &urdf).is_ok());
        let e = parse_urdf(&uses(9), &urdf).unwrap_err().to_string();
        assert!(
            e.contains("mobility.urdf") && e.contains("more than 2000000 triangles in all"),
            "{e}"
        );
    }

    #[test]
    fn nan_or_infinite_origins_and_inertias_are_errors() {
        let joint = r#"<joint name="j" type="revolute"><parent link="base"/><child link="door"/><axis xyz="0 0 1"/><limit lower="0" upper="1"/></joint>"#;
        let e = err_of(&format!(
            r#"<link name="base"><inertial><origin xyz="NaN 0 0"/><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial><visual><geometry><box size="1 1 1"/></geometry></visual></link>
<link name="door"><visual><geometry><box size="0.1 1 1"/></geometry></visual></link>{joint}"#
        ));
        assert!(
            e.contains("link `base` <inertial> <origin xyz/rpy> must be finite"),
            "{e}"
        );
        let e = err_of(&format!(
            r#"<link name="base"><inertial><mass value="1"/><inertia ixx="inf" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial><visual><geometry><box size="1 1 1"/></geometry></visual></link>
<link name="door"><visual><geometry><box size="0.1 1 1"/></geometry></visual></link>{joint}"#
        ));
        assert!(e.contains("link `base` <inertia> must be finite"), "{e}");
        let e = err_of(&format!(
            r#"{BASE}<joint name="j" type="revolute"><origin xyz="0 0 0" rpy="0 NaN 0"/><parent link="base"/><child link="door"/><axis xyz="0 0 1"/><limit lower="0" upper="1"/></joint>"#
        ));
        assert!(
            e.contains("joint `j` <origin xyz/rpy> must be finite"),
            "{e}"
        );
        // The same file with finite numbers loads.
        assert!(parse_urdf(&wrap(&format!("{BASE}{joint}")), Path::new("x.urdf")).is_ok());
    }

    #[test]
    fn hostile_shapes_are_refused_by_name_before_any_reader_recurses() {
        // 15,000 nested unknown elements overflowed the stack (exit 134).
        let deep = format!("{}{}", "<x>".repeat(15_000), "</x>".repeat(15_000));
        let e = err_of(&format!("{BASE}{deep}"));
        assert!(
            e.contains("nested more than 64 deep") && e.contains("mobility.urdf"),
            "{e}"
        );
        // Comments, CDATA and self-closing elements do not count as nesting.
        let joint = r#"<joint name="j" type="revolute"><axis xyz="0 0 1"/><parent link="base"/>
            <child link="door"/><limit lower="0" upper="1"/></joint>"#;
        let flat = format!(
            "{BASE}<!-- <a><b><c> --><![CDATA[<d><e>]]>{joint}{}",
            "<y/>".repeat(200)
        );
        let ok = parse_urdf(&wrap(&flat), Path::new("ok.urdf"));
        assert!(ok.is_ok(), "{:?}", ok.err());
        // Thousands of attributes on one element (quadratic in XML readers).
        let attrs: String = (0..5000).map(|k| format!(" a{k}=\"1\"")).collect();
        let e = err_of(&format!("{BASE}<link name=\"z\"{attrs}/>"));
        assert!(e.contains("5001 attributes; at most 64"), "{e}");
        // More links than the renderer has part slots, refused before any physics.
        let links: String = (0..65).map(|k| format!("<link name=\"l{k}\"/>")).collect();
        let e = err_of(&links);
        assert!(
            e.contains("65 <link> elements; an object may have at most 64"),
            "{e}"
        );
        // A huge file, refused on its size.
        let big = format!("{BASE}<!-- {} -->", "x".repeat(MAX_URDF_BYTES as usize));
        assert!(err_of(&big).contains("URDF files are limited to"));
    }

    #[test]
    fn long_bad_values_are_cut_in_messages() {
        let long = "9".repeat(30) + &"x".repeat(50_000);
        let e = err_of(&format!(
            r#"{BASE}<joint name="j" type="revolute"><parent link="base"/><child link="door"/><origin xyz="{long} 0 0"/></joint>"#
        ));
        assert!(e.len() < 400, "{} bytes: {}", e.len(), &e[..200]);
        assert!(e.contains("50034 bytes") && e.contains("xyz"), "{e}");
    }
}
