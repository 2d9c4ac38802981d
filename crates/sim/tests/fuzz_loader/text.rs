//! Mutated text: generated URDFs and OBJ meshes with numbers, attributes
//! and lines changed, and the corpus of hand-made bad URDFs.

use super::*;

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
