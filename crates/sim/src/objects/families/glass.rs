//! Glass panels: a share of the training instances of the categories that
//! have glass in the world (windows, microwave doors, display cabinets,
//! drinks fridges) get their panels drawn as tinted glass. The geometry and
//! the joints stay as the recipe made them; only the look changes. Held-out
//! instances and the test categories never draw glass by default (see
//! `families::build`), so every published figure keeps its objects;
//! `GlassDraw::All` glazes every instance, oven, washing machine and door
//! included, as a probe.
#![allow(
    clippy::indexing_slicing,
    reason = "the generator indexes parts it created itself; no input reaches it"
)]
use super::super::builder::{Glass, Parts};
use super::parts::{R, u};
use crate::model::JointKind;
use crate::objects::Category;
use rand::Rng;

/// A training instance of a category in [`glazed_panels`] is, with this
/// probability, glazed (`GlassDraw::Training`).
pub(super) const GLASS_SHARE: f64 = 0.35;

/// A panel: a box at most this thick (m, scene size)...
const PANEL_THICK: f32 = 0.045;
/// ...and at least this wide and tall.
const PANEL_SIDE: f32 = 0.12;

/// Which links of a category may hold glass panels: every link of a window
/// (its fixed pane, sashes and casements); the hinged doors of the others.
/// The test categories here draw glass only under `GlassDraw::All`.
fn glazed_panels(category: Category) -> Option<fn(&Parts, usize) -> bool> {
    fn any(_: &Parts, _: usize) -> bool {
        true
    }
    fn hinged(p: &Parts, link: usize) -> bool {
        p.joints
            .iter()
            .any(|j| j.child == link && j.kind == JointKind::Revolute)
    }
    match category {
        Category::Window => Some(any),
        Category::Microwave
        | Category::Refrigerator
        | Category::StorageFurniture
        | Category::Oven
        | Category::WashingMachine
        | Category::Door => Some(hinged),
        _ => None,
    }
}

/// Whether a box (its mesh in the link frame, axis-aligned) is a panel.
fn is_panel(mesh: &crate::mesh::TriMesh) -> bool {
    let Some((lo, hi)) = mesh.bounds() else {
        return false;
    };
    let mut size = (hi - lo).to_array();
    size.sort_by(f32::total_cmp);
    size[0] <= PANEL_THICK && size[1] >= PANEL_SIDE
}

/// Glazes the panels of `p`, with probability `share`, with one glass whose
/// tint and opacity are drawn from `rng`, when the category has glass.
/// Returns whether any panel became glass.
pub(super) fn glaze(category: Category, p: &mut Parts, rng: &mut R, share: f64) -> bool {
    let Some(may_hold) = glazed_panels(category) else {
        return false;
    };
    if share <= 0.0 || !rng.random_bool(share.min(1.0)) {
        return false;
    }
    // Clear to smoked: a pale grey with a faint hue, seen through at 20-60%.
    let grey = u(rng, 0.35, 0.95);
    let hue = [
        u(rng, -0.08, 0.08),
        u(rng, -0.08, 0.08),
        u(rng, -0.08, 0.08),
    ];
    let color = hue.map(|h| (grey + h).clamp(0.0, 1.0));
    let opacity = u(rng, 0.2, 0.6);
    let mut glazed = false;
    for link in 0..p.links.len() {
        if !may_hold(p, link) {
            continue;
        }
        let boxes: Vec<usize> = (0..p.links[link].boxes.len())
            .filter(|&b| is_panel(&p.links[link].boxes[b]))
            .collect();
        if boxes.is_empty() {
            continue;
        }
        glazed = true;
        p.links[link].glass = Some(Glass {
            boxes,
            color,
            opacity,
        });
    }
    glazed
}
