//! From urdf-rs's structure to an [`ObjectModel`]: meshes and colours, the
//! inertials, and the joints ordered as a tree.
use super::{MAX_COORDINATE, MAX_MASS, MIN_MASS, MeshSource, quoted, urdf_err};
use crate::error::Result;
use crate::math::{Mat3, Pose3, Quat, Vec3};
use crate::mesh::{ObjMaterial, TriMesh};
use crate::model::{JointKind, JointModel, LinkModel, ObjectModel, VisualModel};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

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
    meshes: MeshSource<'_>,
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
            if !mesh_path.exists() {
                return Err(urdf_err(
                    file,
                    format!("link `{link}`: mesh file {} not found", mesh_path.display()),
                ));
            }
            // A FIFO or a device where the mesh should be: named as what it is.
            crate::fsio::check_input(&mesh_path, crate::mesh::MAX_OBJ_BYTES)?;
            let mesh = TriMesh::read_obj(&mesh_path)?;
            match scale {
                Some(s) => mesh.scaled(Vec3::from(s.0.map(|v| v as f32))),
                None => mesh,
            }
        }
    })
}

/// A mesh visual's material from its OBJ's MTL file. Its colour takes
/// precedence over the URDF's, as the paper's code loads PartNet-Mobility
/// (PyBullet's `URDF_USE_MATERIAL_COLORS_FROM_MTL`).
fn mtl_material(g: &urdf_rs::Geometry, base_dir: &Path) -> ObjMaterial {
    let urdf_rs::Geometry::Mesh { filename, .. } = g else {
        return ObjMaterial::default();
    };
    mesh_path_in(base_dir, filename)
        .and_then(|path| TriMesh::obj_material(&path))
        .unwrap_or_default()
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

fn material_rgba(m: &Option<urdf_rs::Material>, named: &HashMap<String, [f32; 4]>) -> [f32; 4] {
    // PyBullet's colour for a visual without a material (its
    // getVisualShapeData gives rgba 1 1 1 1): white, apart from the grey floor.
    const DEFAULT: [f32; 4] = [1.0, 1.0, 1.0, 1.0];
    match m {
        Some(m) => match &m.color {
            Some(c) => rgba(c),
            None => named.get(&m.name).copied().unwrap_or(DEFAULT),
        },
        None => DEFAULT,
    }
}

fn rgba(c: &urdf_rs::Color) -> [f32; 4] {
    c.rgba.0.map(|v| v as f32)
}

#[expect(
    clippy::too_many_lines,
    reason = "one pass from parsed URDF to model, in file order; the next to split, by element"
)]
pub(super) fn build_model(
    robot: urdf_rs::Robot,
    path: &Path,
    with_inertial: &HashSet<String>,
    joint_lines: &HashMap<String, u32>,
    meshes: MeshSource<'_>,
) -> Result<ObjectModel> {
    let base_dir = path.parent().unwrap_or(Path::new("."));
    if robot.links.is_empty() {
        return Err(urdf_err(path, "no <link> elements"));
    }
    let named_colors: HashMap<String, [f32; 4]> = robot
        .materials
        .iter()
        .filter_map(|m| m.color.as_ref().map(|c| (m.name.clone(), rgba(c))))
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
            // The MTL's colour wins, as in PyBullet. The opacity is the URDF
            // alpha times the MTL's dissolve: each is a file's own word for how
            // much of what is behind shows through, so a pane is glass whichever
            // file says so. (PyBullet's renderer draws neither.)
            let [r, g, b, alpha] = material_rgba(&v.material, &named_colors);
            let mtl = mtl_material(&v.geometry, base_dir);
            visuals.push(VisualModel {
                mesh_in_link: mesh,
                color: mtl.color.unwrap_or([r, g, b]),
                opacity: alpha * mtl.opacity.unwrap_or(1.0),
            });
        }
        let (mass, com, inertia, derived) = if with_inertial.contains(&l.name) {
            let i = &l.inertial;
            let m = i.mass.value as f32;
            if !(m.is_finite() && (MIN_MASS..=MAX_MASS).contains(&i.mass.value)) {
                return Err(urdf_err(
                    path,
                    format!(
                        "link `{}`: <mass value> must be a positive number of kg within [{MIN_MASS:e}, {MAX_MASS:e}], found {:?}",
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
