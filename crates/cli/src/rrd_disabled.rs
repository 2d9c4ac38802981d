//! `--rrd` in a build without the `rerun` feature: a clear error, before any
//! work is done.
use anyhow::Result;
use std::path::Path;
use umpnet_eval::episode::HookFrame;
use umpnet_sim::render::RendererKind;

pub enum Recorder {}

/// Whether `--rrd` can work in this build.
pub fn check(path: &Path) -> Result<()> {
    Recorder::create(path, "", None).map(|_| ())
}

impl Recorder {
    pub fn create(
        path: &Path,
        _name: &str,
        _display: Option<((u32, u32), RendererKind)>,
    ) -> Result<Self> {
        Err(crate::usage(format!(
            "--rrd {}: this umpnet was built without Rerun support; rebuild it with \
             `cargo install --path crates/cli --features rerun` (or `cargo build --release --features umpnet-cli/rerun`)",
            path.display()
        )))
    }

    pub fn log(&mut self, _h: &HookFrame<'_>) -> Result<()> {
        match *self {}
    }

    pub fn finish(self) -> Result<()> {
        match self {}
    }
}
