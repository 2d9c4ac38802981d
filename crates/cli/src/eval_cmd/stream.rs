//! An evaluation's episodes as a JSON-lines file (`episodes.jsonl`), one
//! episode outcome per line, written as scenes finish, in canonical order
//! (rows as listed, scene index, policies as listed). Read back one line at
//! a time to resume an interrupted run or to merge shards, so memory never
//! holds more than a line. `run.json` beside it says what the run is, so
//! that `--resume` continues only the same evaluation.
use super::report::{Aggregate, EpisodesDigest, RunInfo, Scored};
pub use super::report::{EPISODES, RUN};
use super::tables::RowKey;
use crate::usage;
use anyhow::{Context, Result, bail};
use sha2::{Digest, Sha256};
use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Read, Seek, Write};
use std::path::{Path, PathBuf};
use umpnet_eval::benchmark::Shard;

/// No episode outcome comes near this (a few KB each); a longer line is not one.
const MAX_LINE: u64 = 64 << 20;

/// Appends episode lines and hashes what it wrote. `commit` flushes: a run
/// killed at any moment leaves whole lines, then at most one cut line, which
/// [`resume`] drops.
pub struct EpisodeWriter {
    path: PathBuf,
    file: BufWriter<File>,
    hash: Sha256,
    lines: u64,
}

impl EpisodeWriter {
    /// A new, empty episodes file (replacing one a forced run left).
    pub fn create(path: &Path) -> Result<EpisodeWriter> {
        let file =
            File::create(path).with_context(|| format!("{}: cannot write", path.display()))?;
        Ok(EpisodeWriter {
            path: path.to_path_buf(),
            file: BufWriter::new(file),
            hash: Sha256::new(),
            lines: 0,
        })
    }

    pub fn push(&mut self, line: &str) -> Result<()> {
        self.file
            .write_all(line.as_bytes())
            .and_then(|()| self.file.write_all(b"\n"))
            .with_context(|| format!("{}: cannot write", self.path.display()))?;
        self.hash.update(line.as_bytes());
        self.hash.update(b"\n");
        self.lines += 1;
        Ok(())
    }

    pub fn commit(&mut self) -> Result<()> {
        self.file
            .flush()
            .with_context(|| format!("{}: cannot write", self.path.display()))
    }

    pub fn digest(&self) -> EpisodesDigest {
        EpisodesDigest {
            name: self
                .path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            sha256: format!("sha256:{:x}", self.hash.clone().finalize()),
        }
    }
}

/// Reads an episodes file one complete line at a time, hashing as it goes.
pub struct LineReader {
    path: PathBuf,
    reader: BufReader<File>,
    buf: String,
    hash: Sha256,
    /// Complete lines read, and the bytes they span.
    pub lines: u64,
    pub bytes: u64,
    /// Bytes after the last complete line (a line cut by a kill).
    pub cut: u64,
}

impl LineReader {
    pub fn open(path: &Path) -> Result<LineReader> {
        let meta =
            std::fs::metadata(path).with_context(|| format!("reading {}", path.display()))?;
        if !meta.is_file() {
            bail!("{}: not a regular file", path.display());
        }
        let file = File::open(path).with_context(|| format!("reading {}", path.display()))?;
        Ok(LineReader {
            path: path.to_path_buf(),
            reader: BufReader::with_capacity(16 << 10, file),
            buf: String::new(),
            hash: Sha256::new(),
            lines: 0,
            bytes: 0,
            cut: 0,
        })
    }

    /// The next complete line, without its newline; `None` at the end. A last
    /// line without its newline is not returned (it is counted in `cut`).
    pub fn next_line(&mut self) -> Result<Option<&str>> {
        self.buf.clear();
        let n = (&mut self.reader)
            .take(MAX_LINE)
            .read_line(&mut self.buf)
            .with_context(|| {
                format!(
                    "{} line {}: not UTF-8 text",
                    self.path.display(),
                    self.lines + 1
                )
            })?;
        if n == 0 {
            return Ok(None);
        }
        if !self.buf.ends_with('\n') {
            if n as u64 >= MAX_LINE {
                bail!(
                    "{} line {}: longer than {MAX_LINE} bytes, not an episode outcome",
                    self.path.display(),
                    self.lines + 1
                );
            }
            self.cut = n as u64;
            return Ok(None);
        }
        self.hash.update(self.buf.as_bytes());
        self.lines += 1;
        self.bytes += n as u64;
        Ok(Some(self.buf.trim_end_matches('\n')))
    }

    pub fn sha256(&self) -> String {
        format!("sha256:{:x}", self.hash.clone().finalize())
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl RunInfo {
    /// What line `line` of a shard's episodes file must be: (row, scene
    /// index, policy).
    pub fn expected(
        &self,
        rows: &[RowKey],
        shard: Shard,
        line: u64,
    ) -> Option<(RowKey, u32, &str)> {
        let per_scene = self.policies.len() as u64;
        let scene = line.checked_div(per_scene)?;
        let policy = self.policies.get(usize::try_from(line % per_scene).ok()?)?;
        let (row, k) = shard.scene_at(rows.len() as u64, self.episodes_per_category, scene)?;
        let row = rows.get(usize::try_from(row).ok()?)?;
        Some((row.clone(), k, policy))
    }

    /// Parses line `line` of an episodes file and checks that it is the
    /// episode that belongs there.
    pub fn check_line(
        &self,
        rows: &[RowKey],
        shard: Shard,
        line: u64,
        text: &str,
    ) -> Result<Scored> {
        let s = Scored::parse(text)?;
        let Some((row, k, policy)) = self.expected(rows, shard, line) else {
            bail!("beyond the evaluation's episodes");
        };
        if s.row().as_ref() != Some(&row) || s.index != k || s.policy != policy {
            let found = s.row().map_or("?".into(), |r| r.name().to_owned());
            bail!(
                "holds {found} #{} of `{}` where {} #{k} of `{policy}` belongs",
                s.index,
                s.policy,
                row.name()
            );
        }
        Ok(s)
    }
}

/// run.json: the run's information, its shard and its wall time so far.
#[derive(serde::Serialize, serde::Deserialize)]
pub struct RunState {
    #[serde(flatten)]
    pub run: RunInfo,
    pub shard: String,
    pub wall_seconds: f64,
}

impl RunState {
    pub fn write(&self, dir: &Path) -> Result<()> {
        super::report::write_atomic(&dir.join(RUN), serde_json::to_string(self)?.as_bytes())
    }
}

/// The fields of two runs' information that differ, by name.
pub fn differing_fields(a: &RunInfo, b: &RunInfo) -> Vec<String> {
    let (Ok(serde_json::Value::Object(a)), Ok(serde_json::Value::Object(b))) =
        (serde_json::to_value(a), serde_json::to_value(b))
    else {
        return vec!["(unreadable)".into()];
    };
    a.iter()
        .filter(|(k, v)| b.get(*k) != Some(v))
        .map(|(k, v)| {
            let other = b.get(k).map(|x| x.to_string()).unwrap_or_default();
            format!("{k} ({v} against {other})")
        })
        .collect()
}

/// Where an interrupted run stands: its episodes file (cut back to whole
/// scenes and open for appending), the scenes done and the wall time spent.
pub struct Resumed {
    pub writer: EpisodeWriter,
    pub scenes: u64,
    pub wall_seconds: f64,
}

/// Reads back the run in `dir`, checks it is the evaluation `run` describes
/// (shard included), feeds its whole scenes to `agg` (then hands each line,
/// parsed and as text, to `keep`), and drops
/// a scene whose episodes were not all written.
pub fn resume(
    dir: &Path,
    run: &RunInfo,
    shard: Shard,
    agg: &mut Aggregate,
    mut keep: impl FnMut(Scored, String),
) -> Result<Resumed> {
    if dir.join("results.json").exists() {
        return Err(usage(format!(
            "{}: the evaluation there finished (results.json); nothing to resume",
            dir.display()
        )));
    }
    let state_path = dir.join(RUN);
    let text = std::fs::read_to_string(&state_path).map_err(|e| {
        usage(format!(
            "{}: no run to resume ({e}); start it without --resume",
            state_path.display()
        ))
    })?;
    let state: RunState = serde_json::from_str(&text).with_context(|| {
        format!(
            "{}: not the run.json of `umpnet eval`",
            state_path.display()
        )
    })?;
    let mut diff = differing_fields(run, &state.run);
    if state.shard != shard.to_string() {
        diff.push(format!("shard ({shard} against {})", state.shard));
    }
    if !diff.is_empty() {
        return Err(usage(format!(
            "{}: --resume continues the same evaluation only; these differ: {}",
            dir.display(),
            diff.join("; ")
        )));
    }
    let path = dir.join(EPISODES);
    let rows = run.rows();
    let per_scene = run.policies.len().max(1);
    let mut reader = LineReader::open(&path)?;
    let mut scene: Vec<(Scored, String)> = Vec::with_capacity(per_scene);
    let (mut whole_bytes, mut hash) = (0u64, Sha256::new());
    loop {
        let line = reader.lines;
        let Some(text) = reader.next_line()? else {
            break;
        };
        let s = run
            .check_line(&rows, shard, line, text)
            .with_context(|| format!("{} line {}", path.display(), line + 1))?;
        scene.push((s, text.to_owned()));
        if scene.len() == per_scene {
            for (s, text) in scene.drain(..) {
                agg.add(&s);
                hash.update(text.as_bytes());
                hash.update(b"\n");
                keep(s, text);
            }
            whole_bytes = reader.bytes;
        }
    }
    let lines = (reader.lines / per_scene as u64) * per_scene as u64;
    let file = std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .with_context(|| format!("{}: cannot write", path.display()))?;
    file.set_len(whole_bytes)
        .with_context(|| format!("{}: cannot cut back to whole scenes", path.display()))?;
    let mut file = file;
    file.seek(std::io::SeekFrom::End(0))
        .with_context(|| format!("{}: cannot write", path.display()))?;
    Ok(Resumed {
        writer: EpisodeWriter {
            path,
            file: BufWriter::new(file),
            hash,
            lines,
        },
        scenes: lines / per_scene as u64,
        wall_seconds: state.wall_seconds,
    })
}
