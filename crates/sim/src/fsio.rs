//! Writing files so that a reader (or a second writer) never sees half of one.
use crate::error::{Result, SimError};
use std::path::Path;

/// Writes `bytes` beside `path` under a name unique to this process and
/// write, then renames it over `path`: a crash leaves the old file (or none),
/// never a truncated one, and two writers of one path leave one whole file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(
        ".{name}.{}.{}.tmp",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let io = |file: &Path, source: std::io::Error| SimError::Write {
        file: file.to_path_buf(),
        source,
    };
    std::fs::write(&tmp, bytes).map_err(|e| io(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io(path, e)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_whole_files_and_leaves_no_temporaries() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.json");
        write_atomic(&p, b"first").unwrap();
        write_atomic(&p, b"second, longer").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"second, longer");
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1);
        // Threads writing one path at once leave one of their files, whole.
        std::thread::scope(|s| {
            for k in 0..8u8 {
                let p = &p;
                s.spawn(move || write_atomic(p, &vec![k; 100_000]).unwrap());
            }
        });
        let got = std::fs::read(&p).unwrap();
        assert!(got.len() == 100_000 && got.iter().all(|b| *b == got[0]));
        assert!(write_atomic(&dir.path().join("no/such/dir/x"), b"x").is_err());
    }
}
