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
    if let Err(e) = std::fs::write(&tmp, bytes) {
        // A full disk leaves a partial temporary: it must not stay behind.
        let _ = std::fs::remove_file(&tmp);
        return Err(io(&tmp, e));
    }
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io(path, e)
    })
}

/// Checks a file that input names before reading it: a regular file (after
/// following links; a FIFO or a device would block or never end) of at most
/// `max` bytes. Returns its size.
pub fn check_input(path: &Path, max: u64) -> Result<u64> {
    let io = |source: std::io::Error| SimError::Io {
        file: path.to_path_buf(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(io(std::io::Error::other(
            "not a regular file (a folder, FIFO or device); inputs must be files",
        )));
    }
    if meta.len() > max {
        return Err(io(std::io::Error::other(format!(
            "{} bytes; files of this kind are limited to {max}",
            meta.len()
        ))));
    }
    Ok(meta.len())
}

/// Reads a text file that input names, checked first by [`check_input`];
/// never more than `max` bytes, even if the file grows meanwhile.
pub fn read_text(path: &Path, max: u64) -> Result<String> {
    use std::io::Read;
    check_input(path, max)?;
    let io = |source: std::io::Error| SimError::Io {
        file: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let mut text = String::new();
    file.take(max.saturating_add(1))
        .read_to_string(&mut text)
        .map_err(io)?;
    if text.len() as u64 > max {
        return Err(io(std::io::Error::other(format!(
            "grew past {max} bytes while being read"
        ))));
    }
    Ok(text)
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

    #[test]
    fn inputs_must_be_regular_files_within_their_limit() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        std::fs::write(&p, "hello").unwrap();
        assert_eq!(read_text(&p, 5).unwrap(), "hello");
        let e = read_text(&p, 4).unwrap_err().to_string();
        assert!(e.contains("a.txt") && e.contains("limited to 4"), "{e}");
        let e = read_text(dir.path(), 100).unwrap_err().to_string();
        assert!(e.contains("not a regular file"), "{e}");
        // A device that never ends is refused before a byte is read.
        let e = read_text(Path::new("/dev/zero"), 100)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("/dev/zero") && e.contains("not a regular file"),
            "{e}"
        );
    }
}
