//! The runtime against Python onnxruntime on the fixture package made by
//! `python -m umpnet_train.fixture DIR` (make test sets UMPNET_FIXTURE).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests and benchmarks fail by panicking"
)]
use ndarray::{Array, ArrayD, IxDyn};
use std::path::Path;
use umpnet_policy::ModelPackage;

mod common;
use common::fixture;

fn read_bin(dir: &Path, entry: &serde_json::Value) -> (String, ArrayD<f32>, Vec<i64>) {
    let name = entry["name"].as_str().unwrap().to_string();
    let shape: Vec<usize> = entry["shape"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap() as usize)
        .collect();
    let bytes = std::fs::read(dir.join("reference").join(entry["file"].as_str().unwrap())).unwrap();
    if entry["dtype"] == "int64" {
        let ints: Vec<i64> = bytes
            .chunks_exact(8)
            .map(|c| i64::from_le_bytes(c.try_into().unwrap()))
            .collect();
        (name, ArrayD::zeros(IxDyn(&shape)), ints)
    } else {
        let v: Vec<f32> = bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect();
        (
            name,
            Array::from_shape_vec(IxDyn(&shape), v).unwrap(),
            vec![],
        )
    }
}

fn max_diff(a: &ArrayD<f32>, b: &ArrayD<f32>) -> f32 {
    assert_eq!(a.shape(), b.shape());
    a.iter()
        .zip(b.iter())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn outputs_match_python_onnxruntime() {
    let Some(dir) = fixture() else { return };
    let pkg = ModelPackage::load(&dir, 1, 1, None).unwrap();
    let manifest: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("reference/manifest.json")).unwrap(),
    )
    .unwrap();
    let mut worst = 0.0f32;
    for entry in manifest.as_array().unwrap() {
        let inputs: Vec<_> = entry["inputs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| read_bin(&dir, e))
            .collect();
        let outputs: Vec<_> = entry["outputs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| read_bin(&dir, e))
            .collect();
        let get = |n: &str| inputs.iter().find(|i| i.0 == n).unwrap();
        let ours: Vec<(String, ArrayD<f32>)> = match entry["model"].as_str().unwrap() {
            "position.onnx" => {
                let o = get("observation").1.clone().into_dimensionality().unwrap();
                vec![(
                    "affordance".into(),
                    pkg.position(o.view()).unwrap().into_dyn(),
                )]
            }
            "direction_encoder.onnx" => {
                let o = get("observation").1.clone().into_dimensionality().unwrap();
                let r = get("reference").1.clone().into_dimensionality().unwrap();
                let px = get("pixel").2.clone();
                let p = ndarray::Array2::from_shape_vec((px.len() / 2, 2), px).unwrap();
                let (d, a) = pkg.encode(o.view(), r.view(), p.view()).unwrap();
                vec![
                    ("dist_embedding".into(), d.into_dyn()),
                    ("aot_embedding".into(), a.into_dyn()),
                ]
            }
            _ => {
                let d = get("dist_embedding")
                    .1
                    .clone()
                    .into_dimensionality()
                    .unwrap();
                let a = get("aot_embedding")
                    .1
                    .clone()
                    .into_dimensionality()
                    .unwrap();
                let dir3 = get("direction").1.clone().into_dimensionality().unwrap();
                let s = pkg.decode(d.view(), a.view(), dir3.view()).unwrap();
                vec![
                    ("distance".into(), s.distance.into_dyn()),
                    ("aot_probs".into(), s.aot_probs.into_dyn()),
                ]
            }
        };
        for (name, theirs, _) in &outputs {
            let mine = &ours.iter().find(|o| &o.0 == name).unwrap().1;
            let d = max_diff(mine, theirs);
            assert!(
                d < 1e-4,
                "{}: `{name}` differs from Python onnxruntime by {d}",
                entry["model"]
            );
            worst = worst.max(d);
        }
    }
    eprintln!("max |rust - python onnxruntime| = {worst:.2e}");
}

/// Copies the package in `dir` to `to` with its model.json edited by `edit`,
/// and loads it: the error, or "" when it loads.
fn load_edited(dir: &Path, to: &Path, edit: &dyn Fn(&mut serde_json::Value)) -> String {
    for f in std::fs::read_dir(dir).unwrap() {
        let f = f.unwrap().path();
        if f.is_file() {
            std::fs::copy(&f, to.join(f.file_name().unwrap())).unwrap();
        }
    }
    let mut meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("model.json")).unwrap()).unwrap();
    edit(&mut meta);
    std::fs::write(to.join("model.json"), meta.to_string()).unwrap();
    ModelPackage::load(to, 1, 1, None)
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default()
}

#[test]
fn mismatches_are_reported_in_one_line() {
    let Some(dir) = fixture() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let copy = |edit: &dyn Fn(&mut serde_json::Value)| load_edited(&dir, tmp.path(), edit);
    let e = copy(&|m| m["version"] = 99.into());
    assert!(e.contains("`version` is 99"), "{e}");
    let e = copy(&|m| m["input"]["width"] = 65.into());
    assert!(
        e.contains("input `observation`: expected shape [-1, 48, 65, 10], found [-1, 48, 64, 10]"),
        "{e}"
    );
    let e = copy(&|m| m["embedding"] = 7.into());
    assert!(
        e.contains("`dist_embedding`: expected shape [-1, 7], found [-1, 16]"),
        "{e}"
    );
    // Sizes that would overflow or allocate gigabytes are refused before any tensor exists.
    let e = copy(&|m| m["input"]["height"] = u64::MAX.into());
    assert!(
        e.contains("model.json") && e.contains("limited to 2048"),
        "{e}"
    );
    let e = copy(&|m| {
        m["input"]["height"] = 20_000.into();
        m["input"]["width"] = 20_000.into();
    });
    assert!(
        e.contains("20000x20000") && e.contains("limited to 2048"),
        "{e}"
    );
    let e = copy(&|m| m["embedding"] = u64::MAX.into());
    assert!(e.contains("`embedding`") && e.contains("limited to"), "{e}");
    for outside in ["../position.onnx", "/etc/passwd"] {
        let e = copy(&|m| m["files"]["position"] = outside.into());
        assert!(
            e.contains(outside) && e.contains("expected a file name in the package folder"),
            "{e}"
        );
    }
    let e = copy(&|m| m["files"]["position"] = "nope.onnx".into());
    assert!(e.contains("nope.onnx: missing"), "{e}");
    assert!(!e.contains('\n'));
    // Wrong input size at run time.
    let pkg = ModelPackage::load(&dir, 1, 1, None).unwrap();
    let wrong = ndarray::Array4::<f32>::zeros((1, 10, 10, 10));
    let e = pkg.position(wrong.view()).unwrap_err().to_string();
    assert!(
        e.contains("observation has shape [1, 10, 10, 10], the model takes [batch, 48, 64, 10]"),
        "{e}"
    );
}

#[test]
fn a_joint_net_is_optional_and_checked_like_the_other_networks() {
    let Some(dir) = fixture() else { return };
    let joint = dir.join("joint");
    let pkg = ModelPackage::load(&joint, 1, 1, None).unwrap();
    assert!(pkg.has_joint());
    let obs = ndarray::Array4::<f32>::zeros((2, 48, 64, 10));
    let fields = pkg.joint_fields(obs.view()).unwrap().unwrap();
    assert_eq!(fields.shape(), &[2, 11, 48, 64]);
    // The fixture's JointNet: movable (logit 5), a slide (-5), flow and axis +x.
    assert_eq!(
        fields.slice(ndarray::s![1, .., 7, 9]).to_vec(),
        vec![5.0, -5.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    );
    let plain = ModelPackage::load(&dir, 1, 1, None).unwrap();
    assert!(!plain.has_joint() && plain.joint_fields(obs.view()).unwrap().is_none());

    let tmp = tempfile::tempdir().unwrap();
    let edited = |edit: &dyn Fn(&mut serde_json::Value)| load_edited(&joint, tmp.path(), edit);
    let e = edited(&|m| m["files"]["joint"] = "nope.onnx".into());
    assert!(e.contains("nope.onnx: missing"), "{e}");
    let e = edited(&|m| m["files"]["joint"] = "../joint.onnx".into());
    assert!(
        e.contains("expected a file name in the package folder"),
        "{e}"
    );
    let e = edited(&|m| m["files"]["joint"] = "position.onnx".into());
    assert!(
        e.contains("position.onnx") && e.contains("output `joint_fields` missing"),
        "{e}"
    );
    // The grasp rules that read the JointNet need one; an unknown rule is
    // refused with the names the parser accepts.
    for rule in ["affordance_times_movable", "affordance_times_movable_lever"] {
        let e = edited(&|m| {
            m["files"].as_object_mut().unwrap().remove("joint");
            m["grasp"] = rule.into();
        });
        assert!(
            e.contains(&format!("`grasp`: the `{rule}` grasp")) && e.contains("`files.joint`"),
            "{e}"
        );
    }
    let e = edited(&|m| m["grasp"] = "movable".into());
    assert!(
        e.contains("movable") && e.contains("affordance_times_movable"),
        "{e}"
    );
}
