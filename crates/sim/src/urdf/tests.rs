use super::checks::principal_moments;
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
fn a_visual_without_material_is_white_as_in_pybullet_not_the_floors_grey() {
    let body =
        r#"<link name="base"><visual><geometry><box size="1 1 1"/></geometry></visual></link>"#;
    let m = parse_urdf(&wrap(body), Path::new("obj/mobility.urdf")).unwrap();
    let floor = crate::render::plane_mesh(0).color;
    for link in &m.links {
        assert_eq!(link.visuals[0].color, [1.0, 1.0, 1.0]);
        let apart: f32 = (0..3)
            .map(|k| (link.visuals[0].color[k] - floor[k]).abs())
            .sum();
        assert!(
            apart > 0.9,
            "default colour {:?} too close to the floor {floor:?}",
            link.visuals[0].color
        );
    }
}

/// Each visual of the first link as (opacity, colour).
fn looks_of_base(m: &crate::model::ObjectModel) -> Vec<(f32, [f32; 3])> {
    m.links[0]
        .visuals
        .iter()
        .map(|v| (v.opacity, v.color))
        .collect()
}

#[test]
fn a_material_alpha_below_one_is_glass_whether_given_inline_or_by_name() {
    let body = r#"<material name="tinted"><color rgba="0.6 0.8 0.9 0.35"/></material>
        <link name="base">
          <visual><geometry><box size="1 1 1"/></geometry></visual>
          <visual><geometry><box size="1 1 1"/></geometry><material name="tinted"/></visual>
          <visual><geometry><box size="1 1 1"/></geometry>
            <material name="inline"><color rgba="0.1 0.2 0.3 0.5"/></material></visual>
          <visual><geometry><box size="1 1 1"/></geometry>
            <material name="solid"><color rgba="0.1 0.2 0.3 1"/></material></visual>
        </link>"#;
    let m = parse_urdf(&wrap(body), Path::new("obj/mobility.urdf")).unwrap();
    assert_eq!(
        looks_of_base(&m),
        [
            (1.0, [1.0, 1.0, 1.0]),
            (0.35, [0.6, 0.8, 0.9]),
            (0.5, [0.1, 0.2, 0.3]),
            (1.0, [0.1, 0.2, 0.3])
        ]
    );
    let meshes = crate::env::render_meshes(&m);
    let opacities: Vec<f32> = meshes.iter().map(|r| r.opacity).collect();
    assert_eq!(
        opacities,
        [1.0, 0.35, 0.5, 1.0, 1.0, 1.0],
        "visuals, floor, gripper"
    );
}

#[test]
fn an_mtl_dissolve_below_one_is_glass_and_multiplies_the_urdf_alpha() {
    let dir = tempfile::tempdir().unwrap();
    let objs = dir.path().join("textured_objs");
    std::fs::create_dir_all(&objs).unwrap();
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    // Materials in one library: the dissolve read is the used material's own,
    // its first `d`; `Tr` is not read (exporters disagree on its sense).
    std::fs::write(
        objs.join("looks.mtl"),
        "newmtl pane\nKd 0.6 0.8 0.9\nd 0.4\nd 0.9\n\
         newmtl solid\nKd 0.5 0.5 0.5\nd 1\n\
         newmtl tr_only\nKd 0.5 0.5 0.5\nTr 0.8\n\
         newmtl odd\nKd 0.5 0.5 0.5\nd 7\n\
         newmtl after\nd 0.1\n",
    )
    .unwrap();
    for name in ["pane", "solid", "tr_only", "odd"] {
        std::fs::write(
            objs.join(format!("{name}.obj")),
            format!("mtllib looks.mtl\nusemtl {name}\n{tri}"),
        )
        .unwrap();
    }
    let visual = |obj: &str, alpha: &str| {
        format!(
            r#"<visual><geometry><mesh filename="textured_objs/{obj}.obj"/></geometry>
               <material name="m{obj}{alpha}"><color rgba="0 1 0 {alpha}"/></material></visual>"#
        )
    };
    let urdf = dir.path().join("mobility.urdf");
    std::fs::write(
        &urdf,
        wrap(&format!(
            r#"<link name="base">{}{}{}{}{}</link>"#,
            visual("pane", "1"),
            visual("pane", "0.5"),
            visual("solid", "0.5"),
            visual("tr_only", "1"),
            visual("odd", "1"),
        )),
    )
    .unwrap();
    assert_eq!(
        looks_of_base(&load_urdf(&urdf).unwrap()),
        [
            (0.4, [0.6, 0.8, 0.9]),
            (0.2, [0.6, 0.8, 0.9]),
            (0.5, [0.5, 0.5, 0.5]),
            (1.0, [0.5, 0.5, 0.5]),
            (1.0, [0.5, 0.5, 0.5]),
        ]
    );
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
        e.contains("<joint name=\"j\"> at line") && e.contains("child link `lid` does not exist"),
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
    std::os::unix::fs::symlink(dir.path().join("real.obj"), dir.path().join("alias.obj")).unwrap();
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
