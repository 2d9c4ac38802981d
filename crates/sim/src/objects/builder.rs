//! A small part builder: links made of boxes, joints between them, written out
//! as URDF + one OBJ per link in the PartNet-Mobility layout.
#![allow(
    clippy::indexing_slicing,
    reason = "the generator indexes parts it created itself; no input reaches it"
)]
use crate::math::{Pose3, Vec3};
use crate::mesh::TriMesh;
use crate::model::JointKind;
use std::fmt::Write as _;

pub(crate) struct PartLink {
    pub name: String,
    /// Each box's mesh in the link frame, in the order the recipe gave them.
    pub boxes: Vec<TriMesh>,
    pub color: [f32; 3],
    /// Which boxes are glass, and how it looks.
    pub glass: Option<Glass>,
}

/// Boxes of a link drawn as glass: a tint and an opacity below 1 (the
/// renderer's `RenderMesh::opacity`).
pub(crate) struct Glass {
    pub boxes: Vec<usize>,
    pub color: [f32; 3],
    pub opacity: f32,
}

impl PartLink {
    /// Every box as one mesh.
    pub fn mesh(&self) -> TriMesh {
        self.mesh_of(|_| true)
    }

    /// The boxes that are not glass, as one mesh.
    pub fn opaque_mesh(&self) -> TriMesh {
        self.mesh_of(|b| !self.is_glass(b))
    }

    /// The glass boxes as one mesh; None when the link has none.
    pub fn glass_mesh(&self) -> Option<TriMesh> {
        let g = self.glass.as_ref()?;
        (!g.boxes.is_empty()).then(|| self.mesh_of(|b| self.is_glass(b)))
    }

    fn is_glass(&self, b: usize) -> bool {
        self.glass.as_ref().is_some_and(|g| g.boxes.contains(&b))
    }

    fn mesh_of(&self, keep: impl Fn(usize) -> bool) -> TriMesh {
        let mut mesh = TriMesh::default();
        for (_, b) in self.boxes.iter().enumerate().filter(|(i, _)| keep(*i)) {
            mesh.append(b);
        }
        mesh
    }
}

/// A link's mesh files: (path relative to the URDF, mesh, rgba).
pub(crate) type LinkFiles = Vec<(String, TriMesh, [f32; 4])>;

pub(crate) struct PartJoint {
    pub kind: JointKind,
    pub parent: usize,
    pub child: usize,
    /// Joint origin in the parent link frame (no rotation: axes are given in parent axes).
    pub origin: Vec3,
    pub axis: Vec3,
    pub lower: f32,
    pub upper: f32,
}

/// Builds an object whose link frames all share the object's axes; a child
/// link's frame sits at its joint origin.
#[derive(Default)]
pub(crate) struct Parts {
    pub links: Vec<PartLink>,
    pub joints: Vec<PartJoint>,
    /// Each link's frame origin in the object frame.
    origins: Vec<Vec3>,
}

impl Parts {
    /// The fixed base; `boxes` are (centre, size) in the object frame.
    pub fn base(&mut self, boxes: &[(Vec3, Vec3)], color: [f32; 3]) -> usize {
        self.add_link("base", Vec3::ZERO, boxes, color)
    }

    fn add_link(
        &mut self,
        name: &str,
        origin: Vec3,
        boxes: &[(Vec3, Vec3)],
        color: [f32; 3],
    ) -> usize {
        let boxes = boxes
            .iter()
            .map(|(centre, size)| {
                TriMesh::cuboid(*size).transformed(&Pose3::from_translation(*centre - origin))
            })
            .collect();
        self.links.push(PartLink {
            name: name.to_owned(),
            boxes,
            color,
            glass: None,
        });
        self.origins.push(origin);
        self.links.len() - 1
    }

    /// A moving part: boxes given in the object frame (joint value 0), hinged or
    /// sliding at `joint_origin` (object frame) about/along `axis`.
    #[expect(
        clippy::too_many_arguments,
        reason = "a part's geometry, joint and limits: the recipes name each at the call"
    )]
    pub fn part(
        &mut self,
        parent: usize,
        kind: JointKind,
        joint_origin: Vec3,
        axis: Vec3,
        limits: (f32, f32),
        boxes: &[(Vec3, Vec3)],
        color: [f32; 3],
    ) -> usize {
        let name = format!("link_{}", self.links.len() - 1);
        let child = self.add_link(&name, joint_origin, boxes, color);
        self.joints.push(PartJoint {
            kind,
            parent,
            child,
            origin: joint_origin - self.origins[parent],
            axis: axis.normalize(),
            lower: limits.0,
            upper: limits.1,
        });
        child
    }

    /// Each link's meshes as (file relative to the URDF, mesh, rgba): its
    /// opaque boxes in `original-N.obj` (left out when every box is glass),
    /// then any glass in `glass-N.obj`.
    pub fn meshes(&self) -> Vec<LinkFiles> {
        self.links
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let opaque = l.opaque_mesh();
                let glass = l.glass.as_ref().zip(l.glass_mesh());
                let mut files = Vec::new();
                if !opaque.triangles.is_empty() || glass.is_none() {
                    let [r, g, b] = l.color;
                    let file = format!("textured_objs/original-{i}.obj");
                    files.push((file, opaque, [r, g, b, 1.0]));
                }
                if let Some((glass, mesh)) = glass {
                    let [r, g, b] = glass.color;
                    let file = format!("textured_objs/glass-{i}.obj");
                    files.push((file, mesh, [r, g, b, glass.opacity]));
                }
                files
            })
            .collect()
    }

    /// Every length multiplied by `factor`: meshes, joint origins, slider limits.
    pub fn scale(&mut self, factor: f32) {
        for l in &mut self.links {
            for p in l.boxes.iter_mut().flat_map(|b| &mut b.positions) {
                *p *= factor;
            }
        }
        for o in &mut self.origins {
            *o *= factor;
        }
        for j in &mut self.joints {
            j.origin *= factor;
            if j.kind == JointKind::Prismatic {
                j.lower *= factor;
                j.upper *= factor;
            }
        }
    }

    /// The URDF text. Every link weighs 1 kg, PyBullet's default for the
    /// inertial-less links of PartNet-Mobility, but with its centre of mass at
    /// the middle of its geometry and the inertia of its bounding box (the
    /// default would put it on the hinge, which makes a small part
    /// unmovable by the reference's heavy mount). `files` is [`Parts::meshes`].
    pub fn urdf(&self, name: &str, files: &[LinkFiles]) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "<?xml version=\"1.0\"?>\n<robot name=\"{name}\">");
        for (l, files) in self.links.iter().zip(files) {
            let (lo, hi) = l.mesh().bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
            let size = (hi - lo).max(Vec3::splat(0.005));
            let com = (lo + hi) * 0.5;
            let mass = 1.0f32;
            let ix = mass / 12.0 * (size.y * size.y + size.z * size.z);
            let iy = mass / 12.0 * (size.x * size.x + size.z * size.z);
            let iz = mass / 12.0 * (size.x * size.x + size.y * size.y);
            let _ = writeln!(
                s,
                "  <link name=\"{}\">\n    <inertial>\n      <origin xyz=\"{:.5} {:.5} {:.5}\" rpy=\"0 0 0\"/>\n      <mass value=\"{mass:.5}\"/>\n      <inertia ixx=\"{ix:.6}\" ixy=\"0\" ixz=\"0\" iyy=\"{iy:.6}\" iyz=\"0\" izz=\"{iz:.6}\"/>\n    </inertial>",
                l.name, com.x, com.y, com.z
            );
            for (k, (file, _, [r, g, b, a])) in files.iter().enumerate() {
                // The first material keeps the name files had before glass.
                let material = match k {
                    0 => format!("{}_color", l.name),
                    _ => format!("{}_glass", l.name),
                };
                let _ = writeln!(
                    s,
                    "    <visual>\n      <origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>\n      <geometry><mesh filename=\"{file}\"/></geometry>\n      <material name=\"{material}\"><color rgba=\"{r:.3} {g:.3} {b:.3} {}\"/></material>\n    </visual>",
                    alpha(*a)
                );
            }
            for (file, ..) in files {
                let _ = writeln!(
                    s,
                    "    <collision>\n      <origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>\n      <geometry><mesh filename=\"{file}\"/></geometry>\n    </collision>"
                );
            }
            s.push_str("  </link>\n");
        }
        for (k, j) in self.joints.iter().enumerate() {
            let kind = match j.kind {
                JointKind::Fixed => "fixed",
                JointKind::Revolute => "revolute",
                JointKind::Continuous => "continuous",
                JointKind::Prismatic => "prismatic",
            };
            let _ = writeln!(
                s,
                "  <joint name=\"joint_{k}\" type=\"{kind}\">\n    <origin xyz=\"{:.5} {:.5} {:.5}\" rpy=\"0 0 0\"/>\n    <axis xyz=\"{:.5} {:.5} {:.5}\"/>\n    <parent link=\"{}\"/>\n    <child link=\"{}\"/>\n    <limit lower=\"{:.5}\" upper=\"{:.5}\" effort=\"100\" velocity=\"1\"/>\n    <dynamics damping=\"2\" friction=\"0.5\"/>\n  </joint>",
                j.origin.x,
                j.origin.y,
                j.origin.z,
                j.axis.x,
                j.axis.y,
                j.axis.z,
                self.links[j.parent].name,
                self.links[j.child].name,
                j.lower,
                j.upper
            );
        }
        s.push_str("</robot>\n");
        s
    }
}

/// An alpha as the URDF writes it: `1` for opaque, as files had before glass.
fn alpha(a: f32) -> String {
    if a >= 1.0 {
        "1".into()
    } else {
        format!("{a:.3}")
    }
}
