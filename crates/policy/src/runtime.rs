//! Finding and loading ONNX Runtime. ort panics when its library is missing,
//! so the library is found and checked here first, then loaded once.
use crate::error::{PolicyError, Result};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The shared library version the `api-31` feature expects (PyPI onnxruntime 1.31).
pub const ORT_LIBRARY: &str = "libonnxruntime.so.1.31.1";

static ENVIRONMENT: OnceLock<ort::environment::Environment> = OnceLock::new();
static LOADED: OnceLock<std::result::Result<PathBuf, String>> = OnceLock::new();

/// A `libonnxruntime.so.1.*` in `dir`, if any.
fn versioned_library(dir: &Path) -> Option<PathBuf> {
    std::fs::read_dir(dir)
        .ok()?
        .flatten()
        .map(|e| e.path())
        .find(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("libonnxruntime.so.1."))
        })
}

/// The ONNX Runtime library of the `onnxruntime` package in a Python
/// `site-packages` folder (the exact version this build expects, else another
/// `libonnxruntime.so.1.*`), if it is there. Python's `umpnet.Policy` asks
/// this of its own interpreter's folder.
pub fn library_in_site_packages(site: &Path) -> Option<PathBuf> {
    let capi = site.join("onnxruntime").join("capi");
    let exact = capi.join(ORT_LIBRARY);
    if exact.is_file() {
        return Some(exact);
    }
    versioned_library(&capi)
}

/// `.venv/lib/python3*/site-packages` under `dir` or any of its ancestors.
fn venv_library(dir: &Path) -> Option<PathBuf> {
    for d in dir.ancestors() {
        let lib = d.join(".venv").join("lib");
        if let Ok(entries) = std::fs::read_dir(&lib) {
            for e in entries.flatten() {
                if let Some(p) = library_in_site_packages(&e.path().join("site-packages")) {
                    return Some(p);
                }
            }
        }
    }
    None
}

/// `lib/umpnet/libonnxruntime.so.1.*` under `dir` or any of its ancestors: where
/// `make install-cli` puts the library beside an installed binary.
fn prefix_library(dir: &Path) -> Option<PathBuf> {
    dir.ancestors()
        .find_map(|d| versioned_library(&d.join("lib").join("umpnet")))
}

fn python_library() -> Option<PathBuf> {
    let out = std::process::Command::new("python3")
        .args([
            "-c",
            "import onnxruntime, os; print(os.path.dirname(os.path.dirname(onnxruntime.__file__)))",
        ])
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    library_in_site_packages(Path::new(String::from_utf8_lossy(&out.stdout).trim()))
}

/// Where the library would be loaded from, in order: `explicit`, `ORT_DYLIB_PATH`,
/// the project's `.venv` (from the executable's and the working directory's
/// ancestors), an install prefix's `lib/umpnet` above the executable, the
/// `onnxruntime` of `python3` on PATH.
pub fn find_library(explicit: Option<&Path>) -> Result<PathBuf> {
    if let Some(p) = explicit {
        return if p.is_file() {
            Ok(p.to_path_buf())
        } else {
            Err(PolicyError::Runtime(format!(
                "ONNX Runtime library {} does not exist",
                p.display()
            )))
        };
    }
    if let Some(p) = std::env::var_os("ORT_DYLIB_PATH") {
        let p = PathBuf::from(p);
        return if p.is_file() {
            Ok(p)
        } else {
            Err(PolicyError::Runtime(format!(
                "ORT_DYLIB_PATH={} does not exist",
                p.display()
            )))
        };
    }
    let exe_dir = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(Path::to_path_buf));
    let cwd = std::env::current_dir().ok();
    exe_dir
        .iter()
        .chain(cwd.iter())
        .find_map(|d| venv_library(d))
        .or_else(|| exe_dir.as_deref().and_then(prefix_library))
        .or_else(python_library)
        .ok_or_else(|| {
            PolicyError::Runtime(format!(
                "cannot find {ORT_LIBRARY} (looked at ORT_DYLIB_PATH, in a .venv above the binary \
                 and the working directory, in lib/umpnet above the binary, and in python3's \
                 onnxruntime): set ORT_DYLIB_PATH to \
                 the library, e.g. from `pip install onnxruntime==1.31.1`"
            ))
        })
}

/// The process-wide ONNX Runtime environment, loading the library on first use.
pub fn environment(explicit: Option<&Path>) -> Result<&'static ort::environment::Environment> {
    ensure_loaded(explicit)?;
    ENVIRONMENT
        .get()
        .ok_or_else(|| PolicyError::Runtime("ONNX Runtime environment missing".into()))
}

/// Loads ONNX Runtime once per process; later calls return the same path.
pub fn ensure_loaded(explicit: Option<&Path>) -> Result<PathBuf> {
    LOADED
        .get_or_init(|| {
            let path = find_library(explicit).map_err(|e| match e {
                PolicyError::Runtime(m) => m,
                other => other.to_string(),
            })?;
            let builder =
                ort::init_from(&path).map_err(|e| format!("loading {}: {e}", path.display()))?;
            let env = builder
                .with_name("umpnet")
                .build()
                .map_err(|e| format!("starting ONNX Runtime: {e}"))?;
            // Sessions hold only a weak reference: the environment lives as long as the process.
            let _ = ENVIRONMENT.set(env);
            Ok(path)
        })
        .clone()
        .map_err(PolicyError::Runtime)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_install_prefix_library_is_found_from_the_binary_folder_only_by_its_name() {
        let prefix = tempfile::tempdir().unwrap();
        let bin = prefix.path().join("bin");
        let lib = prefix.path().join("lib").join("umpnet");
        std::fs::create_dir_all(&bin).unwrap();
        std::fs::create_dir_all(&lib).unwrap();
        assert_eq!(prefix_library(&bin), None);
        std::fs::write(lib.join("libonnxruntime.so"), b"").unwrap();
        std::fs::write(lib.join("README"), b"").unwrap();
        assert_eq!(prefix_library(&bin), None, "needs a versioned 1.x library");
        std::fs::write(lib.join("libonnxruntime.so.1.32.0"), b"").unwrap();
        assert_eq!(
            prefix_library(&bin),
            Some(lib.join("libonnxruntime.so.1.32.0"))
        );
    }
}
