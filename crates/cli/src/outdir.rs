//! Output folders: claimed before a long run writes into them, so that two
//! runs never interleave their files and no run overwrites another's results
//! without being told to.
use crate::usage;
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

const LOCK: &str = ".umpnet.lock";

/// Held while a command writes into its output folder; dropping it releases the folder.
pub struct Claim {
    lock: PathBuf,
}

impl Drop for Claim {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.lock);
    }
}

/// Whether the lock names a process that no longer runs (a run killed before
/// it could remove its lock). A lock without a process id, or on a system
/// without /proc, is taken to be held.
fn owner_is_gone(lock: &Path) -> bool {
    let Ok(text) = std::fs::read_to_string(lock) else {
        return false;
    };
    let Ok(pid) = text.trim().parse::<u32>() else {
        return false;
    };
    Path::new("/proc/self").exists() && !Path::new(&format!("/proc/{pid}")).exists()
}

/// Creates `dir` if needed and locks it for this process. Without `force`,
/// refuses a folder that already holds any of `owned` (the files this command
/// writes), or anything at all when `owned` is empty.
pub fn claim(dir: &Path, force: bool, owned: &[&str]) -> Result<Claim> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let lock = dir.join(LOCK);
    let create = || {
        use std::io::Write;
        let mut f = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&lock)?;
        // The owner's process id: a later run can tell a lock whose owner died.
        writeln!(f, "{}", std::process::id())
    };
    let mut made = create();
    if matches!(&made, Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists)
        && owner_is_gone(&lock)
    {
        let _ = std::fs::remove_file(&lock);
        made = create();
    }
    match made {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            return Err(usage(format!(
                "{}: another umpnet run is writing here ({} exists; delete it if no run is)",
                dir.display(),
                lock.display()
            )));
        }
        Err(e) => return Err(e).with_context(|| format!("{}: cannot write", lock.display())),
    }
    let claim = Claim { lock };
    if !force {
        let mut present: Vec<String> = std::fs::read_dir(dir)
            .with_context(|| format!("{}: cannot read", dir.display()))?
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n != LOCK && (owned.is_empty() || owned.contains(&n.as_str())))
            .collect();
        present.sort();
        if !present.is_empty() {
            const SHOWN: usize = 6;
            let more = present.len().saturating_sub(SHOWN);
            present.truncate(SHOWN);
            return Err(usage(format!(
                "{} already holds {}{}; pass --force to write over it",
                dir.display(),
                present.join(", "),
                if more > 0 {
                    format!(" and {more} more")
                } else {
                    String::new()
                }
            )));
        }
    }
    Ok(claim)
}
