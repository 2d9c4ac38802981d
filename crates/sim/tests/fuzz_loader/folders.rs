//! Mutated folders: what can be done to an object's files rather than to
//! their text.

use super::*;

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
