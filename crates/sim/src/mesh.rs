//! Triangle meshes: Wavefront OBJ reading/writing and URDF primitives.
use crate::error::{Result, SimError};
use crate::math::{Pose3, Vec3};
use std::fmt::Write as _;
use std::path::Path;

/// Mesh files larger than this are refused before reading (PartNet-Mobility's
/// meshes are a few MB).
pub const MAX_OBJ_BYTES: u64 = 256 << 20;
/// Largest MTL (material library) file read for an OBJ's colour.
pub const MAX_MTL_BYTES: u64 = 16 << 20;
/// Triangles in one mesh (PartNet-Mobility's largest have about 100k).
pub const MAX_TRIANGLES: usize = 4_000_000;
/// Most triangles an object's visuals may hold in all (meshes reused by
/// several visuals count each time): what one GPU vertex buffer holds
/// (2M x 72 bytes, under wgpu's default 256 MiB), and bounded memory.
pub const MAX_TOTAL_TRIANGLES: usize = 2_000_000;

/// What an OBJ's MTL file says about the first material the OBJ uses.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ObjMaterial {
    /// The diffuse colour, `Kd`, each channel in [0, 1].
    pub color: Option<[f32; 3]>,
    /// The dissolve, `d`, in [0, 1]: 1 is opaque, below 1 is glass.
    pub opacity: Option<f32>,
}

/// An indexed triangle mesh in some frame named by its owner.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles as indices into `positions`, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Adds `other`'s triangles to this mesh (same frame).
    pub fn append(&mut self, other: &TriMesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.triangles.extend(
            other
                .triangles
                .iter()
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
    }

    /// The mesh with every vertex moved by `pose`.
    pub fn transformed(&self, pose: &Pose3) -> TriMesh {
        TriMesh {
            positions: self
                .positions
                .iter()
                .map(|p| pose.transform_point(*p))
                .collect(),
            triangles: self.triangles.clone(),
        }
    }

    /// The mesh scaled per axis.
    pub fn scaled(&self, scale: Vec3) -> TriMesh {
        TriMesh {
            positions: self.positions.iter().map(|p| *p * scale).collect(),
            triangles: self.triangles.clone(),
        }
    }

    /// Axis-aligned bounds, or None for an empty mesh.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))),
        )
    }

    /// Axis-aligned box centred at the origin with the given full size.
    pub fn cuboid(size: Vec3) -> TriMesh {
        let h = size * 0.5;
        let positions = (0..8)
            .map(|i| {
                Vec3::new(
                    if i & 1 == 0 { -h.x } else { h.x },
                    if i & 2 == 0 { -h.y } else { h.y },
                    if i & 4 == 0 { -h.z } else { h.z },
                )
            })
            .collect();
        // Counter-clockwise seen from outside.
        let triangles = vec![
            [0, 2, 1],
            [1, 2, 3], // -z
            [4, 5, 6],
            [5, 7, 6], // +z
            [0, 1, 4],
            [1, 5, 4], // -y
            [2, 6, 3],
            [3, 6, 7], // +y
            [0, 4, 2],
            [2, 4, 6], // -x
            [1, 3, 5],
            [3, 7, 5], // +x
        ];
        TriMesh {
            positions,
            triangles,
        }
    }

    /// Cylinder along +Z centred at the origin (URDF convention).
    pub fn cylinder(radius: f32, length: f32, segments: u32) -> TriMesh {
        let n = segments.max(3);
        let h = length * 0.5;
        let mut positions = Vec::with_capacity(2 * n as usize + 2);
        for i in 0..n {
            let a = i as f32 / n as f32 * std::f32::consts::TAU;
            let (s, c) = a.sin_cos();
            positions.push(Vec3::new(radius * c, radius * s, -h));
            positions.push(Vec3::new(radius * c, radius * s, h));
        }
        let bottom = positions.len() as u32;
        positions.push(Vec3::new(0.0, 0.0, -h));
        positions.push(Vec3::new(0.0, 0.0, h));
        let top = bottom + 1;
        let mut triangles = Vec::with_capacity(4 * n as usize);
        for i in 0..n {
            let j = (i + 1) % n;
            let (b0, t0, b1, t1) = (2 * i, 2 * i + 1, 2 * j, 2 * j + 1);
            triangles.push([b0, b1, t0]);
            triangles.push([t0, b1, t1]);
            triangles.push([bottom, b1, b0]);
            triangles.push([top, t0, t1]);
        }
        TriMesh {
            positions,
            triangles,
        }
    }

    /// UV sphere centred at the origin.
    pub fn sphere(radius: f32, rings: u32, segments: u32) -> TriMesh {
        let (rings, segments) = (rings.max(2), segments.max(3));
        let mut positions = Vec::new();
        for r in 0..=rings {
            let theta = r as f32 / rings as f32 * std::f32::consts::PI;
            for s in 0..segments {
                let phi = s as f32 / segments as f32 * std::f32::consts::TAU;
                positions.push(
                    radius
                        * Vec3::new(
                            theta.sin() * phi.cos(),
                            theta.sin() * phi.sin(),
                            theta.cos(),
                        ),
                );
            }
        }
        let mut triangles = Vec::new();
        for r in 0..rings {
            for s in 0..segments {
                let a = r * segments + s;
                let b = r * segments + (s + 1) % segments;
                let c = a + segments;
                let d = b + segments;
                triangles.push([a, c, b]);
                triangles.push([b, c, d]);
            }
        }
        TriMesh {
            positions,
            triangles,
        }
    }

    /// Reads a Wavefront OBJ file: `v` and `f` records (polygons are fanned;
    /// `v/vt/vn` and negative indices accepted); everything else ignored.
    pub fn read_obj(path: &Path) -> Result<TriMesh> {
        if let Ok(meta) = std::fs::metadata(path)
            && meta.is_file()
            && meta.len() > MAX_OBJ_BYTES
        {
            return Err(SimError::Mesh {
                file: path.to_path_buf(),
                line: 0,
                what: format!(
                    "{} bytes; mesh files are limited to {MAX_OBJ_BYTES}",
                    meta.len()
                ),
            });
        }
        let text = crate::fsio::read_text(path, MAX_OBJ_BYTES)?;
        Self::parse_obj(&text, path)
    }

    /// The first material an OBJ file uses, from the MTL file it names: its
    /// diffuse colour (`Kd`), as PyBullet's `URDF_USE_MATERIAL_COLORS_FROM_MTL`
    /// reads it, and its dissolve (`d`). None when the OBJ names no material
    /// or the MTL cannot be read: looks are decoration, and the URDF's
    /// material stands in.
    pub fn obj_material(path: &Path) -> Option<ObjMaterial> {
        let text = crate::fsio::read_text(path, MAX_OBJ_BYTES).ok()?;
        let mut library = None;
        let mut material = None;
        for line in text.lines() {
            let mut it = line.split_whitespace();
            match it.next() {
                Some("mtllib") if library.is_none() => library = it.next().map(str::to_owned),
                Some("usemtl") if material.is_none() => material = it.next().map(str::to_owned),
                _ => {}
            }
            if library.is_some() && material.is_some() {
                break;
            }
        }
        // Only a file beside the OBJ: an object must not make the loader read elsewhere.
        let library = library.filter(|l| !l.contains(['/', '\\']) && l != "..")?;
        // A material library is a few lines; a FIFO, device or huge file is skipped.
        let mtl_path = path.with_file_name(library);
        // Not through a link to elsewhere: the library must really sit beside the OBJ.
        let beside = match (mtl_path.canonicalize(), path.canonicalize()) {
            (Ok(m), Ok(o)) => m.parent() == o.parent(),
            _ => false,
        };
        if !beside {
            return None;
        }
        let mtl = crate::fsio::read_text(&mtl_path, MAX_MTL_BYTES).ok()?;
        let material = material?;
        let mut current = false;
        let mut found = ObjMaterial::default();
        for line in mtl.lines() {
            let mut it = line.split_whitespace();
            let keyword = it.next();
            if keyword == Some("newmtl") {
                if current {
                    break;
                }
                current = it.next() == Some(material.as_str());
                continue;
            }
            if !current {
                continue;
            }
            let numbers: Vec<f32> = it.filter_map(|t| t.parse().ok()).collect();
            let finite = numbers.iter().all(|c| c.is_finite());
            match (keyword, &numbers[..]) {
                (Some("Kd"), &[r, g, b]) if finite && found.color.is_none() => {
                    found.color = Some([r, g, b].map(|c| c.clamp(0.0, 1.0)));
                }
                // `Tr` is left alone: exporters disagree on which way it runs,
                // and opaque is the safe reading.
                (Some("d"), &[d]) if finite && found.opacity.is_none() => {
                    found.opacity = Some(d.clamp(0.0, 1.0));
                }
                _ => {}
            }
        }
        Some(found)
    }

    /// A Wavefront OBJ's triangles (polygons fanned), errors naming `path` and the line.
    pub fn parse_obj(text: &str, path: &Path) -> Result<TriMesh> {
        let err = |line: usize, what: String| SimError::Mesh {
            file: path.to_path_buf(),
            line,
            what,
        };
        let mut mesh = TriMesh::default();
        let mut faces: Vec<(usize, Vec<(i64, i64)>)> = Vec::new();
        let mut triangles = 0usize;
        for (i, line) in text.lines().enumerate() {
            let lineno = i + 1;
            let mut it = line.split_whitespace();
            match it.next() {
                Some("v") => {
                    let mut xyz = [0f32; 3];
                    for c in &mut xyz {
                        let tok = it
                            .next()
                            .ok_or_else(|| err(lineno, "vertex needs 3 coordinates".into()))?;
                        *c = tok.parse().map_err(|_| {
                            err(lineno, format!("vertex coordinate `{tok}` is not a number"))
                        })?;
                        if !c.is_finite() {
                            return Err(err(
                                lineno,
                                format!("vertex coordinate `{tok}` is not finite"),
                            ));
                        }
                    }
                    mesh.positions.push(Vec3::from(xyz));
                }
                Some("f") => {
                    let idx = it
                        .map(|tok| {
                            let first = tok.split('/').next().unwrap_or("");
                            first.parse::<i64>().map_err(|_| {
                                err(lineno, format!("face index `{tok}` is not an integer"))
                            })
                        })
                        .collect::<Result<Vec<_>>>()?;
                    if idx.len() < 3 {
                        return Err(err(lineno, "face needs at least 3 vertices".into()));
                    }
                    triangles += idx.len() - 2;
                    if triangles > MAX_TRIANGLES {
                        return Err(err(
                            lineno,
                            format!("more than {MAX_TRIANGLES} triangles in one mesh"),
                        ));
                    }
                    // A negative index counts back from the vertices read so far.
                    let seen = mesh.positions.len() as i64;
                    let idx: Vec<(i64, i64)> = idx
                        .into_iter()
                        .map(|k| (k, if k < 0 { seen + k + 1 } else { k }))
                        .collect();
                    faces.push((lineno, idx));
                }
                _ => {}
            }
        }
        let n = mesh.positions.len() as i64;
        for (lineno, idx) in faces {
            let resolved = idx
                .iter()
                .map(|&(k, one_based)| {
                    let r = one_based - 1;
                    if (0..n).contains(&r) {
                        Ok(r as u32)
                    } else {
                        Err(err(
                            lineno,
                            format!("face index {k} out of range 1..={n} (or -1 back to -N)"),
                        ))
                    }
                })
                .collect::<Result<Vec<_>>>()?;
            // A polygon as a fan around its first vertex.
            if let Some((&first, rest)) = resolved.split_first() {
                for pair in rest.windows(2) {
                    if let [a, b] = *pair {
                        mesh.triangles.push([first, a, b]);
                    }
                }
            }
        }
        if mesh.triangles.is_empty() {
            return Err(err(0, "mesh has no faces".into()));
        }
        Ok(mesh)
    }

    /// The mesh as Wavefront OBJ text.
    pub fn to_obj(&self) -> String {
        let mut s = String::with_capacity(self.positions.len() * 32 + self.triangles.len() * 16);
        for p in &self.positions {
            let _ = writeln!(s, "v {:.6} {:.6} {:.6}", p.x, p.y, p.z);
        }
        for t in &self.triangles {
            let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn obj_roundtrip_and_polygon_fan() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1/1/1 2/2/2 3 4\n";
        let m = TriMesh::parse_obj(text, Path::new("q.obj")).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        let again = TriMesh::parse_obj(&m.to_obj(), Path::new("q.obj")).unwrap();
        assert_eq!(again, m);
    }

    #[test]
    fn negative_indices_count_back_from_the_vertices_read_so_far() {
        // Two quads, each written with relative indices right after its vertices.
        let quad = |z: f32| format!("v 0 0 {z}\nv 1 0 {z}\nv 1 1 {z}\nv 0 1 {z}\nf -4 -3 -2 -1\n");
        let relative = format!("{}{}", quad(0.0), quad(1.0));
        let m = TriMesh::parse_obj(&relative, Path::new("r.obj")).unwrap();
        let absolute = relative.replacen("f -4 -3 -2 -1", "f 1 2 3 4", 1).replacen(
            "f -4 -3 -2 -1",
            "f 5 6 7 8",
            1,
        );
        let a = TriMesh::parse_obj(&absolute, Path::new("a.obj")).unwrap();
        assert_eq!(m, a);
        assert_eq!(
            m.triangles,
            vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]]
        );
        // Back past the first vertex: named as written.
        let e = TriMesh::parse_obj(
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nf -4 -2 -1\n",
            Path::new("b.obj"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("b.obj:4") && e.contains("face index -4"), "{e}");
    }

    #[test]
    fn obj_errors_name_line() {
        let e = TriMesh::parse_obj("v 0 0 0\nv 1 x 0\n", Path::new("bad.obj")).unwrap_err();
        assert_eq!(
            e.to_string(),
            "bad.obj:2: vertex coordinate `x` is not a number"
        );
        let e = TriMesh::parse_obj("v 0 0 0\nf 1 2 3\n", Path::new("b.obj")).unwrap_err();
        assert!(
            e.to_string().contains("b.obj:2: face index 2 out of range"),
            "{e}"
        );
    }

    #[test]
    fn cuboid_faces_point_outward() {
        let m = TriMesh::cuboid(Vec3::new(1.0, 2.0, 3.0));
        for t in &m.triangles {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            let n = (b - a).cross(c - a);
            let centre = (a + b + c) / 3.0;
            assert!(n.dot(centre) > 0.0, "inward face {t:?}");
        }
    }
}
