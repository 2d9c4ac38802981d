//! The loader fuzzer: mutated generated URDFs and OBJ meshes, plus a corpus of
//! hand-made bad files, must each load into a finite, usable model or fail
//! with a typed error. A panic, a NaN in a loaded model or a NaN out of the
//! physics fails the test (proptest shrinks it to a small reproduction).
//!
//! Fixed seeds: the same cases run everywhere, in about half a minute in
//! release builds. Raise `UMPNET_FUZZ_CASES` for a longer hunt.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests and benchmarks fail by panicking"
)]
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed, TestCaseError, TestRunner};
use std::cell::Cell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use umpnet_sim::SimError;
use umpnet_sim::math::{Pose3, Vec3};
use umpnet_sim::mesh::TriMesh;
use umpnet_sim::objects::{Category, GeneratedObject, PARTNET_SCALE, generate};
use umpnet_sim::physics::{Articulation, PhysicsConfig, PhysicsProfile};
use umpnet_sim::urdf::{ObjectModel, parse_urdf_with};

/// Numbers that are valid but extreme: the physics must stay finite on them.
const NUMBERS: &[&str] = &[
    "0", "-0", "1", "-1", "0.5", "-0.5", "2", "1e-45", "1e-30", "1e-6", "1e6", "1e30", "3.4e38",
    "-3.4e38", "100", "0.001", "3.14159", "-3.14159", "6.3", "1e-300", "-1e30",
];

/// Values that have broken loaders before: non-numbers, overflow to f32
/// infinity, subnormals, signs where sizes go, markup and escapes.
const TOKENS: &[&str] = &[
    "NaN",
    "nan",
    "inf",
    "-inf",
    "1e39",
    "-1e39",
    "1e-45",
    "0",
    "-0",
    "-1",
    "-0.5",
    "1e308",
    "0x10",
    "1,2",
    "",
    " ",
    "<",
    ">",
    "\"",
    "&",
    "&amp;",
    "&#0;",
    "\u{feff}",
    "\u{0}",
    "é",
    "<!--",
    "]]>",
    "</link>",
    "<link name=\"base\"/>",
    "<link name=\"extra\"/>",
    "<inertial/>",
    "<limit/>",
    "<axis xyz=\"0 0 0\"/>",
    "<mass value=\"-1\"/>",
    "<joint name=\"j\" type=\"revolute\"><parent link=\"base\"/><child link=\"base\"/></joint>",
    "type=\"floating\"",
    "type=\"continuous\"",
    "type=\"planar\"",
    "../../../etc/passwd",
    "/etc/passwd",
    "textured_objs/missing.obj",
    "f 1 2 99999",
    "f 0 0 0",
    "f -1 -2 -3",
    "f 1/1/1 2//2 3",
    "v 1 2",
    "v NaN 0 0",
    "vn 0 0 0",
    "mtllib ../x.mtl",
    "&#x110000;",
    "&#xD800;",
    "&#1114112;",
    "<mimic joint=\"nowhere\"/>",
    "<mimic/>",
    "<mimic joint=\"j\" multiplier=\"nan\"/>",
    "<limit effort=\"1\" velocity=\"1\"/>",
];

#[derive(Clone, Debug)]
enum Mutation {
    /// Replace the k-th number in the text with one of [`NUMBERS`].
    Number(usize, usize),
    /// Replace the k-th quoted attribute value.
    Attribute(usize, usize),
    Insert(f64, usize),
    Delete(f64, usize),
    Duplicate(f64, usize, f64),
    Truncate(f64),
    SwapLines(usize, usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let token = 0..TOKENS.len();
    prop_oneof![
        4 => (any::<usize>(), 0..NUMBERS.len()).prop_map(|(k, t)| Mutation::Number(k, t)),
        3 => (any::<usize>(), token.clone()).prop_map(|(k, t)| Mutation::Attribute(k, t)),
        2 => (0.0..1.0f64, token).prop_map(|(at, t)| Mutation::Insert(at, t)),
        1 => (0.0..1.0f64, 1..200usize).prop_map(|(at, n)| Mutation::Delete(at, n)),
        1 => (0.0..1.0f64, 1..400usize, 0.0..1.0f64)
            .prop_map(|(at, n, to)| Mutation::Duplicate(at, n, to)),
        1 => (0.0..1.0f64).prop_map(Mutation::Truncate),
        1 => (any::<usize>(), any::<usize>()).prop_map(|(a, b)| Mutation::SwapLines(a, b)),
    ]
}

/// The nearest char boundary at or before `fraction` of the text.
fn boundary(text: &str, fraction: f64) -> usize {
    let mut at = ((text.len() as f64) * fraction) as usize;
    at = at.min(text.len());
    while !text.is_char_boundary(at) {
        at -= 1;
    }
    at
}

fn ranges_of(text: &str, number: bool) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if number {
            let starts = b[i].is_ascii_digit() || (b[i] == b'-' && i + 1 < b.len());
            if starts && (i == 0 || !b[i - 1].is_ascii_alphanumeric()) {
                let s = i;
                i += 1;
                while i < b.len() && matches!(b[i], b'0'..=b'9' | b'.' | b'e' | b'E' | b'-' | b'+')
                {
                    i += 1;
                }
                out.push((s, i));
                continue;
            }
        } else if b[i] == b'"'
            && let Some(len) = b[i + 1..].iter().position(|c| *c == b'"')
        {
            out.push((i + 1, i + 1 + len));
            i += len + 2;
            continue;
        }
        i += 1;
    }
    out
}

fn apply(text: &str, m: &Mutation) -> String {
    let replace = |(s, e): (usize, usize), t: &str| format!("{}{t}{}", &text[..s], &text[e..]);
    match *m {
        Mutation::Number(k, t) | Mutation::Attribute(k, t) => {
            let number = matches!(m, Mutation::Number(..));
            let ranges = ranges_of(text, number);
            let token = if number { NUMBERS[t] } else { TOKENS[t] };
            match ranges.len() {
                0 => text.to_owned(),
                n => replace(ranges[k % n], token),
            }
        }
        Mutation::Insert(at, t) => {
            let at = boundary(text, at);
            replace((at, at), TOKENS[t])
        }
        Mutation::Delete(at, n) => {
            let s = boundary(text, at);
            let e = boundary(
                text,
                ((s + n).min(text.len())) as f64 / text.len().max(1) as f64,
            );
            format!("{}{}", &text[..s], &text[e.max(s)..])
        }
        Mutation::Duplicate(at, n, to) => {
            let s = boundary(text, at);
            let e = boundary(
                text,
                ((s + n).min(text.len())) as f64 / text.len().max(1) as f64,
            );
            let piece = &text[s..e.max(s)];
            let to = boundary(text, to);
            format!("{}{}{}", &text[..to], piece, &text[to..])
        }
        Mutation::Truncate(at) => text[..boundary(text, at)].to_owned(),
        Mutation::SwapLines(a, b) => {
            let mut lines: Vec<&str> = text.lines().collect();
            if !lines.is_empty() {
                let n = lines.len();
                lines.swap(a % n, b % n);
            }
            lines.join("\n")
        }
    }
}

fn finite3(v: Vec3) -> bool {
    v.is_finite()
}

/// What "loaded" promises: every number the physics and renderer read is
/// finite (limits may be infinite only on continuous joints) and sane.
fn check_model(m: &ObjectModel) -> Result<(), TestCaseError> {
    prop_assert!(!m.links.is_empty(), "a model without links loaded");
    prop_assert!(m.root < m.links.len());
    for l in &m.links {
        prop_assert!(
            l.mass.is_finite() && l.mass > 0.0,
            "link {} mass {}",
            l.name,
            l.mass
        );
        prop_assert!(
            finite3(l.com_in_link),
            "link {} com {:?}",
            l.name,
            l.com_in_link
        );
        prop_assert!(
            l.inertia_in_link
                .to_cols_array()
                .iter()
                .all(|x| x.is_finite()),
            "link {} inertia {:?}",
            l.name,
            l.inertia_in_link
        );
        for v in &l.visuals {
            prop_assert!(v.color.iter().all(|c| c.is_finite()));
            prop_assert!(v.mesh_in_link.positions.iter().all(|p| finite3(*p)));
            let n = v.mesh_in_link.positions.len() as u32;
            prop_assert!(
                v.mesh_in_link.triangles.iter().flatten().all(|i| *i < n),
                "index out of range"
            );
        }
    }
    for j in &m.joints {
        prop_assert!(j.parent < m.links.len() && j.child < m.links.len());
        prop_assert!(finite3(j.parent_from_joint.translation));
        prop_assert!(j.parent_from_joint.rotation.is_finite());
        prop_assert!(
            finite3(j.axis_in_joint) && (j.axis_in_joint.length() - 1.0).abs() < 1e-3,
            "joint {} axis {:?}",
            j.name,
            j.axis_in_joint
        );
        prop_assert!(!j.lower.is_nan() && !j.upper.is_nan() && j.lower <= j.upper);
        if j.kind.is_movable() && j.kind != umpnet_sim::urdf::JointKind::Continuous {
            prop_assert!(
                j.lower.is_finite() && j.upper.is_finite(),
                "joint {} limits",
                j.name
            );
        }
        prop_assert!(j.damping.is_finite() && j.friction.is_finite());
    }
    Ok(())
}

/// Grasps each movable joint's child at its centre of mass and pulls it two
/// ways: the joint values must stay finite and within the limits.
fn check_physics(m: ObjectModel, profile: PhysicsProfile) -> Result<(), TestCaseError> {
    let m = Arc::new(m);
    for (j, joint) in m.movable_joints().take(2) {
        let mut art = Articulation::new(
            m.clone(),
            Pose3::IDENTITY,
            PhysicsConfig::with_profile(profile),
        );
        let q0 = art.joint_position(j);
        prop_assert!(
            q0 >= joint.lower && q0 <= joint.upper,
            "joint {} starts at {q0}, outside [{}, {}]",
            joint.name,
            joint.lower,
            joint.upper
        );
        let link = joint.child;
        let at = art
            .world_from_link(link)
            .transform_point(m.links[link].com_in_link);
        if art.attach(at, link).is_err() {
            continue;
        }
        for dir in [Vec3::X, -Vec3::Y, Vec3::Z] {
            match art.move_gripper(dir, j) {
                Ok(_) => {}
                Err(SimError::InvalidAction(_)) => break,
                Err(e) => return Err(TestCaseError::fail(format!("move_gripper: {e}"))),
            }
            let q = art.joint_position(j);
            prop_assert!(q.is_finite(), "joint {} became {q}", joint.name);
            prop_assert!(
                q >= joint.lower - 1e-2 && q <= joint.upper + 1e-2,
                "joint {} at {q} outside [{}, {}]",
                joint.name,
                joint.lower,
                joint.upper
            );
        }
    }
    Ok(())
}

fn cases(default: u32) -> u32 {
    std::env::var("UMPNET_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn runner(cases: u32, seed: u64) -> TestRunner {
    TestRunner::new(Config {
        cases,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        max_shrink_iters: 2000,
        ..Config::default()
    })
}

/// One generated object per category, with the in-memory meshes it refers to.
fn seeds() -> Vec<GeneratedObject> {
    Category::ALL.iter().map(|&c| generate(c, 1, 7)).collect()
}

fn load(obj: &GeneratedObject, text: &str) -> umpnet_sim::Result<ObjectModel> {
    let dir = PathBuf::from(format!("fuzz/{}/{}", obj.category.name(), obj.index));
    let meshes: HashMap<PathBuf, &TriMesh> = obj
        .meshes
        .iter()
        .map(|(rel, m)| (dir.join(rel), m))
        .collect();
    parse_urdf_with(text, &dir.join("mobility.urdf"), &|p| {
        meshes.get(p).map(|m| (*m).clone())
    })
}

#[test]
fn mutated_urdfs_load_finite_or_fail_typed() {
    let objects = seeds();
    let strategy = (
        0..objects.len(),
        prop::collection::vec(mutation(), 1..4),
        any::<bool>(),
    );
    let (loaded, refused) = (Cell::new(0u32), Cell::new(0u32));
    let result =
        runner(cases(3000), 0x0a11_ce5e).run(&strategy, |(which, mutations, reference)| {
            let obj = &objects[which];
            let text = mutations.iter().fold(obj.urdf.clone(), |t, m| apply(&t, m));
            check_urdf(obj, &text, reference, &loaded, &refused).map_err(|e| {
                TestCaseError::fail(format!(
                    "{e}\nlines changed by the mutation:\n{}",
                    changed_lines(&obj.urdf, &text)
                ))
            })
        });
    if let Err(e) = result {
        panic!("{e}");
    }
    let (loaded, refused) = (loaded.get(), refused.get());
    eprintln!("URDF fuzzer: {loaded} loaded, {refused} refused");
    // Mutations must exercise both sides, or the fuzzer tests nothing.
    assert!(
        loaded > 300 && refused > 300,
        "{loaded} loaded, {refused} refused"
    );
}

/// The lines of `mutated` that `original` lacks: the reproduction to read.
fn changed_lines(original: &str, mutated: &str) -> String {
    let before: std::collections::HashSet<&str> = original.lines().collect();
    mutated
        .lines()
        .filter(|l| !before.contains(l))
        .collect::<Vec<_>>()
        .join("\n")
}

fn check_urdf(
    obj: &GeneratedObject,
    text: &str,
    reference: bool,
    loaded: &Cell<u32>,
    refused: &Cell<u32>,
) -> Result<(), TestCaseError> {
    match load(obj, text) {
        Ok(model) => {
            loaded.set(loaded.get() + 1);
            check_model(&model)?;
            let model = model
                .scaled(PARTNET_SCALE)
                .map_err(|e| TestCaseError::fail(format!("scaling a loaded model: {e}")))?;
            check_model(&model)?;
            let profile = if reference {
                PhysicsProfile::Reference
            } else {
                PhysicsProfile::Ideal
            };
            check_physics(model, profile)?;
        }
        Err(e) => {
            refused.set(refused.get() + 1);
            let msg = e.to_string();
            prop_assert!(
                !msg.is_empty() && msg.len() < 2000,
                "error message of {} bytes",
                msg.len()
            );
        }
    }
    Ok(())
}

#[test]
fn mutated_obj_meshes_parse_finite_or_fail_typed() {
    let objects = seeds();
    let texts: Vec<String> = objects
        .iter()
        .flat_map(|o| o.meshes.iter().take(2).map(|(_, m)| m.to_obj()))
        .collect();
    let strategy = (0..texts.len(), prop::collection::vec(mutation(), 1..4));
    let (parsed, refused) = (Cell::new(0u32), Cell::new(0u32));
    let result = runner(cases(1500), 0x0b1_0b1).run(&strategy, |(which, mutations)| {
        let text = mutations
            .iter()
            .fold(texts[which].clone(), |t, m| apply(&t, m));
        match TriMesh::parse_obj(&text, Path::new("fuzz.obj")) {
            Ok(mesh) => {
                parsed.set(parsed.get() + 1);
                prop_assert!(mesh.positions.iter().all(|p| p.is_finite()));
                let n = mesh.positions.len() as u32;
                prop_assert!(
                    mesh.triangles.iter().flatten().all(|i| *i < n),
                    "index out of range"
                );
            }
            Err(SimError::Mesh { line, .. }) => {
                refused.set(refused.get() + 1);
                prop_assert!(line <= text.lines().count() + 1, "error at line {line}");
            }
            Err(e) => return Err(TestCaseError::fail(format!("untyped mesh error: {e:?}"))),
        }
        Ok(())
    });
    if let Err(e) = result {
        panic!("{e}");
    }
    let (parsed, refused) = (parsed.get(), refused.get());
    eprintln!("OBJ fuzzer: {parsed} parsed, {refused} refused");
    assert!(
        parsed > 50 && refused > 50,
        "{parsed} parsed, {refused} refused"
    );
}

/// Hand-made bad files, each naming in its first line the message it must get:
/// `<!-- expect: ... -->`.
#[test]
fn corpus_of_bad_urdfs_is_refused_with_the_expected_message() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "urdf"))
        .collect();
    files.sort();
    assert!(files.len() >= 20, "corpus has only {} files", files.len());
    let mut wrong = Vec::new();
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap();
        let expect = text
            .lines()
            .next()
            .and_then(|l| l.strip_prefix("<!-- expect: "))
            .and_then(|l| l.strip_suffix(" -->"))
            .unwrap_or_else(|| {
                panic!(
                    "{}: first line must be <!-- expect: ... -->",
                    file.display()
                )
            });
        match umpnet_sim::urdf::load_urdf(file) {
            Ok(_) => wrong.push(format!(
                "{}: loaded, expected an error containing {expect:?}",
                file.display()
            )),
            Err(e) => {
                let msg = e.to_string();
                if !msg.contains(expect) || !msg.contains(&file.display().to_string()) {
                    wrong.push(format!(
                        "{}: error {msg:?} does not contain {expect:?} and the file",
                        file.display()
                    ));
                }
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// What can be done to an object's folder rather than to its text: links in
/// and out of it, FIFOs where files should be, material libraries that never
/// end, one large mesh reused until the total passes the cap, coupled joints.
#[derive(Clone, Debug)]
enum FolderMutation {
    /// The k-th mesh becomes a symbolic link to a file outside the folder.
    MeshLinksOut(usize),
    /// The k-th mesh becomes a symbolic link to another mesh of the folder.
    MeshLinksIn(usize, usize),
    /// The k-th mesh becomes a FIFO (a read would block forever).
    MeshIsFifo(usize),
    /// The k-th mesh names a material library that is `/dev/zero` (through a
    /// link) or a FIFO.
    EndlessMtl(usize, bool),
    /// The k-th mesh becomes one of `faces` triangles, and every visual of
    /// the first link is repeated `copies` times.
    HugeTotal(usize, usize, usize),
    /// The k-th joint mimics the j-th (or itself when they are equal).
    Mimic(usize, usize),
}

fn folder_mutation() -> impl Strategy<Value = FolderMutation> {
    let k = any::<usize>();
    prop_oneof![
        k.prop_map(FolderMutation::MeshLinksOut),
        (k, k).prop_map(|(a, b)| FolderMutation::MeshLinksIn(a, b)),
        k.prop_map(FolderMutation::MeshIsFifo),
        (k, any::<bool>()).prop_map(|(a, b)| FolderMutation::EndlessMtl(a, b)),
        (k, 100_000..600_000usize, 1..8usize)
            .prop_map(|(a, f, c)| FolderMutation::HugeTotal(a, f, c)),
        (k, k).prop_map(|(a, b)| FolderMutation::Mimic(a, b)),
    ]
}

/// Applies `m` to the object written at `urdf`; returns what the load must
/// then do: `Some(text)` when it must fail with an error containing `text`.
/// A mesh is changed once per case (`touched`): a FIFO must not be opened
/// again by a later mutation, and a later one would undo the earlier.
fn apply_to_folder(
    urdf: &Path,
    meshes: &[PathBuf],
    m: &FolderMutation,
    outside: &Path,
    touched: &mut Vec<usize>,
) -> Option<&'static str> {
    let index = |k: usize| k % meshes.len();
    let pick = |k: usize| &meshes[index(k)];
    let mesh_of = |m: &FolderMutation| match *m {
        FolderMutation::MeshLinksOut(k)
        | FolderMutation::MeshIsFifo(k)
        | FolderMutation::EndlessMtl(k, _)
        | FolderMutation::HugeTotal(k, _, _) => vec![index(k)],
        FolderMutation::MeshLinksIn(k, j) => vec![index(k), index(j)],
        FolderMutation::Mimic(..) => vec![],
    };
    let uses = mesh_of(m);
    if uses.iter().any(|k| touched.contains(k)) {
        return None;
    }
    touched.extend(uses);
    let fifo = |p: &Path| {
        std::fs::remove_file(p).ok();
        let ok = std::process::Command::new("mkfifo")
            .arg(p)
            .status()
            .unwrap()
            .success();
        assert!(ok, "mkfifo {}", p.display());
    };
    match *m {
        FolderMutation::MeshLinksOut(k) => {
            std::fs::remove_file(pick(k)).unwrap();
            std::os::unix::fs::symlink(outside, pick(k)).unwrap();
            Some("leaves the object's folder")
        }
        FolderMutation::MeshLinksIn(k, j) => {
            let (from, to) = (pick(k), pick(j));
            if from != to {
                std::fs::remove_file(from).unwrap();
                std::os::unix::fs::symlink(to.file_name().unwrap(), from).unwrap();
            }
            None
        }
        FolderMutation::MeshIsFifo(k) => {
            fifo(pick(k));
            Some("not a regular file")
        }
        FolderMutation::EndlessMtl(k, through_link) => {
            let mesh = pick(k);
            let text = std::fs::read_to_string(mesh).unwrap_or_default();
            std::fs::write(mesh, format!("mtllib trap.mtl\nusemtl m\n{text}")).ok();
            let trap = mesh.with_file_name("trap.mtl");
            if through_link {
                std::os::unix::fs::symlink("/dev/zero", &trap).ok();
            } else {
                fifo(&trap);
            }
            None
        }
        FolderMutation::HugeTotal(k, faces, copies) => {
            let mut obj = String::from("v 0 0 0\nv 0.01 0 0\nv 0 0.01 0\n");
            obj += &"f 1 2 3\n".repeat(faces);
            std::fs::write(pick(k), obj).unwrap();
            let text = std::fs::read_to_string(urdf).unwrap();
            // Every <visual> of the file repeated: the reused mesh counts each time.
            let mut out = String::new();
            let mut rest = text.as_str();
            while let Some(s) = rest.find("<visual") {
                let Some(e) = rest[s..]
                    .find("</visual>")
                    .map(|e| s + e + "</visual>".len())
                else {
                    break;
                };
                out += &rest[..e];
                for _ in 1..copies {
                    out += &rest[s..e];
                }
                rest = &rest[e..];
            }
            out += rest;
            std::fs::write(urdf, out).unwrap();
            (faces * copies > umpnet_sim::mesh::MAX_TOTAL_TRIANGLES).then_some("triangles in all")
        }
        FolderMutation::Mimic(k, j) => {
            let text = std::fs::read_to_string(urdf).unwrap();
            let names: Vec<&str> = text
                .match_indices("<joint name=\"")
                .map(|(i, pat)| {
                    let rest = &text[i + pat.len()..];
                    &rest[..rest.find('"').unwrap()]
                })
                .collect();
            if names.is_empty() {
                return None;
            }
            let (a, b) = (names[k % names.len()], names[j % names.len()]);
            let at = text.find(&format!("<joint name=\"{a}\"")).unwrap();
            let close = at + text[at..].find('>').unwrap() + 1;
            let out = format!("{}<mimic joint=\"{b}\"/>{}", &text[..close], &text[close..]);
            std::fs::write(urdf, out).unwrap();
            Some("<mimic")
        }
    }
}

/// Loads `urdf` on a thread and waits a bounded time: a read that blocks (a
/// FIFO) fails the test instead of hanging it.
fn load_with_deadline(urdf: PathBuf) -> Result<umpnet_sim::Result<ObjectModel>, TestCaseError> {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || tx.send(umpnet_sim::urdf::load_urdf(&urdf)).ok());
    rx.recv_timeout(std::time::Duration::from_secs(30))
        .map_err(|_| TestCaseError::fail("the load did not finish in 30 s (a blocking read?)"))
}

#[test]
fn mutated_object_folders_load_finite_or_fail_typed_and_never_block() {
    let objects = seeds();
    let root = tempfile::tempdir().unwrap();
    let outside = root.path().join("outside.obj");
    std::fs::write(&outside, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let strategy = (
        0..objects.len(),
        prop::collection::vec(folder_mutation(), 1..3),
    );
    let case = Cell::new(0u32);
    let (loaded, refused) = (Cell::new(0u32), Cell::new(0u32));
    let result = runner(cases(120), 0xf01d_e125).run(&strategy, |(which, mutations)| {
        case.set(case.get() + 1);
        let obj = &objects[which];
        let dir = root.path().join(format!("case{}", case.get()));
        let urdf = obj.write(&dir).unwrap();
        let meshes: Vec<PathBuf> = obj
            .meshes
            .iter()
            .map(|(rel, _)| urdf.with_file_name(rel))
            .collect();
        let mut touched = Vec::new();
        let expected: Vec<&str> = mutations
            .iter()
            .filter_map(|m| apply_to_folder(&urdf, &meshes, m, &outside, &mut touched))
            .collect();
        let outcome = load_with_deadline(urdf.clone())?;
        std::fs::remove_dir_all(&dir).ok();
        match outcome {
            Ok(model) => {
                loaded.set(loaded.get() + 1);
                prop_assert!(
                    expected.is_empty(),
                    "{mutations:?} loaded; expected an error with {expected:?}"
                );
                check_model(&model)?;
                let triangles: usize = model
                    .links
                    .iter()
                    .flat_map(|l| &l.visuals)
                    .map(|v| v.mesh_in_link.triangles.len())
                    .sum();
                prop_assert!(
                    triangles <= umpnet_sim::mesh::MAX_TOTAL_TRIANGLES,
                    "{triangles} triangles loaded"
                );
            }
            Err(e) => {
                refused.set(refused.get() + 1);
                let msg = e.to_string();
                prop_assert!(
                    !msg.is_empty() && msg.len() < 2000,
                    "error message of {} bytes",
                    msg.len()
                );
                if !expected.is_empty() {
                    prop_assert!(
                        expected.iter().any(|x| msg.contains(x)),
                        "{mutations:?}: {msg:?} says none of {expected:?}"
                    );
                }
            }
        }
        Ok(())
    });
    if let Err(e) = result {
        panic!("{e}");
    }
    let (loaded, refused) = (loaded.get(), refused.get());
    eprintln!("folder fuzzer: {loaded} loaded, {refused} refused");
    assert!(
        loaded > 10 && refused > 10,
        "{loaded} loaded, {refused} refused"
    );
}
