//! Which share of a benchmark's scenes one run takes (`eval --shard K/N`).
use crate::{EvalError, Result};

/// Shard `index` of `count` (1-based, as `--shard 2/4`): the scenes whose
/// position in the canonical order (categories as listed, then scene index)
/// is `index - 1` modulo `count`. Round-robin, so every shard gets a mix of
/// categories and about the same work; the union of all shards is the whole
/// benchmark, each scene exactly once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// Which shard, from 1.
    pub index: u32,
    /// How many shards.
    pub count: u32,
}

impl Shard {
    /// The whole benchmark.
    pub const ALL: Shard = Shard { index: 1, count: 1 };

    /// Shard `index` of `count`, or an error unless 1 <= index <= count.
    pub fn new(index: u32, count: u32) -> Result<Shard> {
        if count == 0 || index == 0 || index > count {
            return Err(EvalError::Episode(format!(
                "shard {index}/{count}: expected K/N with 1 <= K <= N"
            )));
        }
        Ok(Shard { index, count })
    }

    /// Whether this shard is the whole benchmark.
    pub fn is_all(self) -> bool {
        self.count == 1
    }

    /// Whether the scene at `position` of the canonical order is this shard's.
    pub fn holds(self, position: u64) -> bool {
        position % u64::from(self.count.max(1)) == u64::from(self.index.saturating_sub(1))
    }
}

impl Default for Shard {
    fn default() -> Self {
        Shard::ALL
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl std::str::FromStr for Shard {
    type Err = EvalError;
    fn from_str(s: &str) -> Result<Shard> {
        let bad = || EvalError::Episode(format!("shard `{s}`: expected K/N, e.g. 2/4"));
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let k = k.trim().parse().map_err(|_| bad())?;
        let n = n.trim().parse().map_err(|_| bad())?;
        Shard::new(k, n)
    }
}

impl Shard {
    /// How many of the `rows x per_row` scenes this shard holds.
    pub fn scene_count(self, rows: u64, per_row: u32) -> u64 {
        let total = rows.saturating_mul(u64::from(per_row));
        let first = u64::from(self.index.saturating_sub(1));
        if total > first {
            (total - first).div_ceil(u64::from(self.count.max(1)))
        } else {
            0
        }
    }

    /// This shard's scene `i` of `rows x per_row`, as (row number, index),
    /// in canonical order.
    pub fn scene_at(self, rows: u64, per_row: u32, i: u64) -> Option<(u64, u32)> {
        if i >= self.scene_count(rows, per_row) {
            return None;
        }
        let position = u64::from(self.index.saturating_sub(1))
            .checked_add(i.checked_mul(u64::from(self.count))?)?;
        let per_row = u64::from(per_row);
        Some((position / per_row, u32::try_from(position % per_row).ok()?))
    }
}
