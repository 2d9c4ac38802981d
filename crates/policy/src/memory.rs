//! What a learned policy carries from one move to the next within an
//! episode: the moves that moved nothing (not tried again until a move
//! does) and the previous move (for the `prev90` filter). One rule for the
//! benchmark's policy and the Python `Policy.act`.
use nalgebra::Vector3;

/// The memory of one episode; `clear` at its start.
#[derive(Clone, Debug, Default)]
pub struct EpisodeMemory {
    banned: Vec<Vector3<f32>>,
    previous: Option<Vector3<f32>>,
}

impl EpisodeMemory {
    /// A new episode: nothing banned, no previous move.
    pub fn clear(&mut self) {
        self.banned.clear();
        self.previous = None;
    }

    /// After a move along `direction`: one that moved the part lifts every
    /// ban; one that did not is banned.
    pub fn record(&mut self, direction: Vector3<f32>, moved: bool) {
        if moved {
            self.banned.clear();
        } else {
            self.banned.push(direction);
        }
        self.previous = Some(direction);
    }

    /// A memory as saved elsewhere (`banned` and `previous` as they were):
    /// a robot loop's session between calls.
    pub fn from_parts(banned: Vec<Vector3<f32>>, previous: Option<Vector3<f32>>) -> Self {
        Self { banned, previous }
    }

    /// The directions not to choose again.
    pub fn banned(&self) -> &[Vector3<f32>] {
        &self.banned
    }

    /// The last move, if any.
    pub fn previous(&self) -> Option<Vector3<f32>> {
        self.previous
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_move_that_moved_nothing_is_banned_until_one_moves() {
        let mut m = EpisodeMemory::default();
        let (x, y) = (Vector3::x(), Vector3::y());
        assert!(m.banned().is_empty() && m.previous().is_none());
        m.record(x, false);
        m.record(y, false);
        assert_eq!(m.banned(), &[x, y]);
        assert_eq!(m.previous(), Some(y));
        m.record(x, true);
        assert!(m.banned().is_empty());
        assert_eq!(m.previous(), Some(x));
        m.record(y, false);
        m.clear();
        assert!(m.banned().is_empty() && m.previous().is_none());
    }
}
