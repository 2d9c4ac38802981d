//! Opening a package's ONNX networks and checking what they take and
//! return, each error naming the network's file.

use super::pkg_err;
use crate::error::{PolicyError, Result};
use ort::session::Session;
use std::path::{Path, PathBuf};

pub(super) fn ort_err(file: &Path, e: impl std::fmt::Display) -> PolicyError {
    PolicyError::Runtime(format!("{}: {e}", file.display()))
}

/// Checks a session's tensor names and (static) shapes; -1 = any.
pub(super) fn check_io(
    file: &Path,
    session: &Session,
    inputs: &[(&str, Vec<i64>)],
    outputs: &[(&str, Vec<i64>)],
) -> Result<()> {
    for (kind, outlets, wanted) in [
        ("input", session.inputs(), inputs),
        ("output", session.outputs(), outputs),
    ] {
        for (name, shape) in wanted {
            let Some(o) = outlets.iter().find(|o| o.name() == *name) else {
                let found: Vec<&str> = outlets.iter().map(|o| o.name()).collect();
                return Err(pkg_err(
                    file,
                    format!("{kind} `{name}` missing; found {found:?}"),
                ));
            };
            let found: Vec<i64> = o
                .dtype()
                .tensor_shape()
                .map(|s| s.iter().copied().collect())
                .unwrap_or_default();
            let ok = found.len() == shape.len()
                && found
                    .iter()
                    .zip(shape)
                    .all(|(f, e)| *e < 0 || *f < 0 || f == e);
            if !ok {
                return Err(pkg_err(
                    file,
                    format!("{kind} `{name}`: expected shape {shape:?}, found {found:?}"),
                ));
            }
        }
    }
    Ok(())
}

/// Opens the network `name` of the package in `dir` in a session.
pub(super) fn open_network(
    env: &ort::environment::Environment,
    dir: &Path,
    meta_path: &Path,
    name: &str,
    threads: usize,
) -> Result<(PathBuf, Session)> {
    // A file beside model.json: `../` or an absolute path would make
    // a package load networks from anywhere.
    let plain = std::path::Path::new(name)
        .file_name()
        .is_some_and(|f| f == std::ffi::OsStr::new(name));
    if !plain {
        return Err(pkg_err(
            meta_path,
            format!("`files` names `{name}`; expected a file name in the package folder"),
        ));
    }
    let file = dir.join(name);
    if !file.is_file() {
        return Err(pkg_err(&file, "missing (named in model.json `files`)"));
    }
    let s = Session::builder(env)
        .and_then(|b| b.with_intra_threads(threads.max(1)).map_err(Into::into))
        .and_then(|mut b| b.commit_from_file(&file))
        .map_err(|e| ort_err(&file, e))?;
    Ok((file, s))
}

/// A network's output with every value finite, or an error naming the
/// network's file and the output: a NaN would otherwise pass as a choice
/// (the first pixel, a "success").
pub(super) fn finite<D: ndarray::Dimension>(
    a: ndarray::Array<f32, D>,
    file: &Path,
    name: &str,
) -> Result<ndarray::Array<f32, D>> {
    match a.iter().position(|v| !v.is_finite()) {
        None => Ok(a),
        Some(i) => Err(pkg_err(
            file,
            format!(
                "output `{name}` holds {} (value {i} of {}); the network is broken or its input out of range",
                a.iter().nth(i).copied().unwrap_or(f32::NAN),
                a.len()
            ),
        )),
    }
}

/// Every value of a network's output within `lo..=hi`, or an error naming it.
pub(super) fn in_range<D: ndarray::Dimension>(
    a: &ndarray::Array<f32, D>,
    file: &Path,
    name: &str,
    (lo, hi): (f32, f32),
) -> Result<()> {
    match a.iter().find(|v| !(lo..=hi).contains(*v)) {
        None => Ok(()),
        Some(v) => Err(pkg_err(
            file,
            format!("output `{name}` holds {v}, outside [{lo}, {hi}]"),
        )),
    }
}

/// A named output of a run, or an error naming the file: a package whose graph
/// lacks it fails here instead of panicking in ort's indexing.
pub(super) fn output<'a>(
    out: &'a ort::session::SessionOutputs<'_>,
    name: &str,
    file: &Path,
) -> Result<&'a ort::value::DynValue> {
    out.get(name)
        .ok_or_else(|| pkg_err(file, format!("the graph has no output `{name}`")))
}
