//! The way to a goal read off two frames (beyond the paper; the `goal45`
//! direction filter). Each frame's camera is recovered from the frame itself;
//! the points of the goal frame that stand where the current frame shows
//! empty space are where the part is going, and the points of the current
//! frame that stand where the goal frame shows empty space are where it is.
//! The shift between the two says which way to move; hidden points say
//! nothing either way, so a part that swings out of view is not mistaken
//! for one that went away.
#![allow(
    clippy::indexing_slicing,
    reason = "pixels are read inside the dimensions checked on entry and bounds-checked projections"
)]
use crate::CHANNELS;
use crate::observation::point_at;
use nalgebra::{DMatrix, Matrix3x4, Vector3, Vector4};
use ndarray::ArrayView3;

/// How far (m) a point must stand in front of the surface another frame
/// shows at its pixel to count as in that frame's empty space: depth noise
/// and the thickness of a part's edge stay under it.
pub const FREE_SPACE_MARGIN: f32 = 0.015;
/// Points farther than this from the gripper (m) are not compared: a part
/// moves less than this within one goal.
pub const REACH: f32 = 0.9;

/// The camera a frame was seen through, recovered from the frame itself: the
/// 3 x 4 projection that takes each pixel's world point to the pixel's
/// centre (direct linear transform), scaled so that its third coordinate is
/// the depth along the optical axis. Observations carry world points, not
/// the camera; this keeps the runtime's inputs as they are.
#[derive(Clone, Debug)]
pub struct Pinhole {
    projection: Matrix3x4<f64>,
}

/// A camera fit is trusted when its median reprojection error is below this (pixels).
const MAX_REPROJECTION_PX: f64 = 0.5;

impl Pinhole {
    /// Fits the projection to (up to 400) pixels with depth spread over the
    /// image; None when they are too few, degenerate, or fit badly.
    pub fn fit(observation: &ArrayView3<'_, f32>) -> Option<Self> {
        let (h, w, c) = observation.dim();
        if c != CHANNELS {
            return None;
        }
        let valid: Vec<(usize, usize)> = (0..h)
            .flat_map(|r| (0..w).map(move |c| (r, c)))
            .filter(|&(r, c)| {
                observation[[r, c, 9]] > 0.0 && (0..3).all(|k| observation[[r, c, k]].is_finite())
            })
            .collect();
        if valid.len() < 12 {
            return None;
        }
        let stride = valid.len().div_ceil(400).max(1);
        let sample: Vec<(Vector3<f64>, [f64; 2])> = valid
            .iter()
            .step_by(stride)
            .map(|&(r, c)| {
                let p = Vector3::new(
                    f64::from(observation[[r, c, 0]]),
                    f64::from(observation[[r, c, 1]]),
                    f64::from(observation[[r, c, 2]]),
                );
                (p, [c as f64 + 0.5, r as f64 + 0.5])
            })
            .collect();
        // Hartley's normalisation: centred, unit-scaled points and pixels.
        let n = sample.len() as f64;
        let mean_p = sample.iter().map(|(p, _)| p).sum::<Vector3<f64>>() / n;
        let scale_p = (sample.iter().map(|(p, _)| (p - mean_p).norm()).sum::<f64>() / n).max(1e-9);
        let mean_u = [0, 1].map(|k| sample.iter().map(|(_, u)| u[k]).sum::<f64>() / n);
        let scale_u = (sample
            .iter()
            .map(|(_, u)| ((u[0] - mean_u[0]).powi(2) + (u[1] - mean_u[1]).powi(2)).sqrt())
            .sum::<f64>()
            / n)
            .max(1e-9);
        let mut a = DMatrix::<f64>::zeros(2 * sample.len(), 12);
        for (i, (p, u)) in sample.iter().enumerate() {
            let x = (p - mean_p) / scale_p;
            let x = [x.x, x.y, x.z, 1.0];
            let (un, vn) = ((u[0] - mean_u[0]) / scale_u, (u[1] - mean_u[1]) / scale_u);
            for k in 0..4 {
                a[(2 * i, k)] = x[k];
                a[(2 * i, 8 + k)] = -un * x[k];
                a[(2 * i + 1, 4 + k)] = x[k];
                a[(2 * i + 1, 8 + k)] = -vn * x[k];
            }
        }
        let svd = a.svd(false, true);
        let v_t = svd.v_t?;
        let k = svd.singular_values.imin();
        let row = v_t.row(k);
        let pn = Matrix3x4::from_row_slice(&row.iter().copied().collect::<Vec<f64>>());
        // Undo the normalisations: P = T_u^-1 Pn T_p.
        let t_p = nalgebra::Matrix4::new(
            1.0 / scale_p,
            0.0,
            0.0,
            -mean_p.x / scale_p,
            0.0,
            1.0 / scale_p,
            0.0,
            -mean_p.y / scale_p,
            0.0,
            0.0,
            1.0 / scale_p,
            -mean_p.z / scale_p,
            0.0,
            0.0,
            0.0,
            1.0,
        );
        let t_u_inv = nalgebra::Matrix3::new(
            scale_u, 0.0, mean_u[0], 0.0, scale_u, mean_u[1], 0.0, 0.0, 1.0,
        );
        let mut projection = t_u_inv * pn * t_p;
        // Depth along the optical axis: the third row's direction is unit
        // and points are in front.
        let norm = Vector3::new(projection[(2, 0)], projection[(2, 1)], projection[(2, 2)]).norm();
        if norm < 1e-12 || !norm.is_finite() {
            return None;
        }
        projection /= norm;
        if (projection * sample[0].0.push(1.0))[2] < 0.0 {
            projection = -projection;
        }
        let pinhole = Self { projection };
        let mut errors: Vec<f64> = sample
            .iter()
            .map(|(p, u)| match pinhole.project64(*p) {
                Some((x, y, _)) => ((x - u[0]).powi(2) + (y - u[1]).powi(2)).sqrt(),
                None => f64::INFINITY,
            })
            .collect();
        errors.sort_by(f64::total_cmp);
        (errors[errors.len() / 2] < MAX_REPROJECTION_PX).then_some(pinhole)
    }

    fn project64(&self, p: Vector3<f64>) -> Option<(f64, f64, f64)> {
        let q = self.projection * Vector4::new(p.x, p.y, p.z, 1.0);
        (q[2] > 1e-6).then(|| (q[0] / q[2], q[1] / q[2], q[2]))
    }

    /// The camera's centre (world frame); None for a degenerate projection.
    pub fn centre(&self) -> Option<Vector3<f32>> {
        let m = self.projection.fixed_view::<3, 3>(0, 0).into_owned();
        let c = -m.try_inverse()? * self.projection.column(3);
        c.iter().all(|v| v.is_finite()).then(|| c.cast::<f32>())
    }

    /// The pixel (column, row, as real numbers) and depth of a world point
    /// in front of the camera.
    pub fn project(&self, p: Vector3<f32>) -> Option<(f32, f32, f32)> {
        self.project64(p.cast::<f64>())
            .map(|(x, y, z)| (x as f32, y as f32, z as f32))
    }
}

/// Where the part goes between two frames, read off the frames alone: the
/// points of `target` that lie in space `current` shows empty (where the
/// part will be) and the points of `current` that lie in space `target`
/// shows empty (where it is, and the gripper holding it), near `near`.
#[derive(Clone, Debug, PartialEq)]
pub struct Change {
    /// Mean of the arriving points minus mean of the departing ones (m).
    pub shift: Vector3<f32>,
    /// The goal frame shows none of the part's new place (fewer than
    /// [`MIN_CHANGED`] points arrive): `shift` is then the unit direction
    /// away from its camera through the departing points, where hidden
    /// places lie.
    pub hidden: bool,
    /// How many points arrive.
    pub arriving: usize,
    /// How many points depart.
    pub departing: usize,
}

/// Fewest departing points for a [`Change`] to say anything, and fewest
/// arriving ones for it to read the goal's place off the goal frame.
pub const MIN_CHANGED: usize = 5;

/// The points of `a` within [`REACH`] of `near` that `b`'s camera sees empty
/// space behind: in front of `b`'s surface at their pixel by more than
/// [`FREE_SPACE_MARGIN`]. A pixel of `b` without depth says nothing: it is a
/// depth camera's hole (glass, dark or shiny surfaces) as often as open
/// space, and taking holes for open space reads a glass part's motion
/// backwards (the points behind where it is now seem to arrive).
fn vacated(
    a: &ArrayView3<'_, f32>,
    b: &ArrayView3<'_, f32>,
    camera: &Pinhole,
    near: Vector3<f32>,
) -> Vec<Vector3<f32>> {
    let (h, w, _) = a.dim();
    let (hb, wb, _) = b.dim();
    let mut out = Vec::new();
    for r in 0..h {
        for c in 0..w {
            if a[[r, c, 9]] <= 0.0 {
                continue;
            }
            let p = point_at(a, (r, c));
            if !p.iter().all(|v| v.is_finite()) || (p - near).norm() > REACH {
                continue;
            }
            let Some((x, y, z)) = camera.project(p) else {
                continue;
            };
            if x < 0.0 || y < 0.0 || x as usize >= wb || y as usize >= hb {
                continue;
            }
            let seen = b[[y as usize, x as usize, 9]];
            if seen > 0.0 && z < seen - FREE_SPACE_MARGIN {
                out.push(p);
            }
        }
    }
    out
}

/// The change from `current` to `target` about `near`; None when the
/// frames' cameras cannot be recovered or fewer than [`MIN_CHANGED`] points
/// depart (nothing to move).
pub fn change(
    current: &ArrayView3<'_, f32>,
    target: &ArrayView3<'_, f32>,
    near: Vector3<f32>,
) -> Option<Change> {
    if current.dim() != target.dim() {
        return None;
    }
    let goal_camera = Pinhole::fit(target)?;
    let arriving = vacated(target, current, &Pinhole::fit(current)?, near);
    let departing = vacated(current, target, &goal_camera, near);
    if departing.len() < MIN_CHANGED {
        return None;
    }
    let mean = |v: &[Vector3<f32>]| v.iter().sum::<Vector3<f32>>() / v.len() as f32;
    let hidden = arriving.len() < MIN_CHANGED;
    let shift = if hidden {
        // The goal frame hides where the part goes: behind what it shows,
        // deeper along the rays through where the part is now.
        let from = mean(&departing);
        (from - goal_camera.centre()?).try_normalize(1e-6)?
    } else {
        mean(&arriving) - mean(&departing)
    };
    Some(Change {
        shift,
        hidden,
        arriving: arriving.len(),
        departing: departing.len(),
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use ndarray::Array3;

    const FX: f32 = 100.0;
    const CX: f32 = 32.0;
    const CY: f32 = 24.0;

    /// A 64 x 48 observation through a camera at the origin looking down +z
    /// (x right, y down) of a wall at z = 2 and, in front of it, a 0.4 m
    /// square panel at depth `panel_z` centred at (`panel_x`, 0).
    fn scene(panel_x: f32, panel_z: f32) -> Array3<f32> {
        let (h, w) = (48, 64);
        let mut obs = Array3::<f32>::zeros((h, w, CHANNELS));
        for r in 0..h {
            for c in 0..w {
                let (u, v) = ((c as f32 + 0.5 - CX) / FX, (r as f32 + 0.5 - CY) / FX);
                // The panel where its ray meets it, else the wall.
                let (x, y) = (u * panel_z, v * panel_z);
                let z = if (x - panel_x).abs() < 0.2 && y.abs() < 0.2 {
                    panel_z
                } else {
                    2.0
                };
                obs[[r, c, 0]] = u * z;
                obs[[r, c, 1]] = v * z;
                obs[[r, c, 2]] = z;
                obs[[r, c, 9]] = z;
            }
        }
        obs
    }

    #[test]
    fn the_camera_is_recovered_from_the_frame() {
        let obs = scene(0.0, 1.2);
        let camera = Pinhole::fit(&obs.view()).unwrap();
        let (x, y, z) = camera.project(Vector3::new(0.3, -0.1, 1.5)).unwrap();
        assert!((x - (0.3 / 1.5 * FX + CX)).abs() < 1e-3, "{x}");
        assert!((y - (-0.1 / 1.5 * FX + CY)).abs() < 1e-3, "{y}");
        assert!((z - 1.5).abs() < 1e-4, "depth along the axis: {z}");
        assert!(
            camera.project(Vector3::new(0.0, 0.0, -1.0)).is_none(),
            "behind"
        );
        // A frame whose points no pinhole explains is refused.
        let mut bad = obs.clone();
        for r in 0..48 {
            for c in 0..64 {
                bad[[r, c, 0]] = ((r * 7 + c * 13) % 17) as f32 * 0.1;
            }
        }
        assert!(Pinhole::fit(&bad.view()).is_none());
    }

    #[test]
    fn the_shift_points_from_where_the_part_is_to_where_it_goes() {
        let near = Vector3::new(0.0, 0.0, 1.2);
        // Pulled toward the camera and to the right.
        let c = change(&scene(0.0, 1.2).view(), &scene(0.2, 0.9).view(), near).unwrap();
        assert!(c.shift.x > 0.1 && c.shift.z < -0.1, "{c:?}");
        // The same frames the other way round: the way back.
        let back = change(&scene(0.2, 0.9).view(), &scene(0.0, 1.2).view(), near).unwrap();
        assert!(back.shift.x < -0.1 && back.shift.z > 0.1, "{back:?}");
        // Nothing changes: nothing to say.
        assert!(change(&scene(0.0, 1.2).view(), &scene(0.0, 1.2).view(), near).is_none());
    }

    /// The scene with the moving panel of glass, seen by a depth camera
    /// that reads nothing on it (observations hold zeros there), and a
    /// static opaque block at depth 1.5 to its left (so that the camera is
    /// recovered from more than the flat wall).
    fn glass_panel(panel_x: f32, panel_z: f32) -> Array3<f32> {
        let mut obs = scene(panel_x, panel_z);
        for r in 0..48 {
            for c in 0..64 {
                let (u, v) = ((c as f32 + 0.5 - CX) / FX, (r as f32 + 0.5 - CY) / FX);
                let (x, y) = (u * 1.5, v * 1.5);
                if (x + 0.35).abs() < 0.1 && y.abs() < 0.1 && obs[[r, c, 9]] > 1.5 {
                    for (k, value) in [(0, x), (1, y), (2, 1.5), (9, 1.5)] {
                        obs[[r, c, k]] = value;
                    }
                }
            }
        }
        for mut px in obs.rows_mut() {
            if px[9] == panel_z {
                px.fill(0.0);
            }
        }
        obs
    }

    #[test]
    fn holes_in_depth_say_nothing_about_where_the_part_goes() {
        // The panel pulled toward the camera and to the right, both frames
        // without depth on it: only the wall is seen, and it does not move.
        // Holes taken for open space would read the wall behind each hole as
        // the part, and the shift the wrong way (to the left).
        let near = Vector3::new(0.0, 0.0, 1.2);
        let current = glass_panel(0.0, 1.2);
        let target = glass_panel(0.2, 0.9);
        assert!(Pinhole::fit(&current.view()).is_some() && Pinhole::fit(&target.view()).is_some());
        assert_eq!(change(&current.view(), &target.view(), near), None);
        // With depth on the panel in the goal frame alone, the way is read
        // from the goal's points: to the right and toward the camera.
        let c = change(&current.view(), &scene(0.2, 0.9).view(), near);
        assert!(c.as_ref().is_none_or(|c| c.shift.x > 0.0), "{c:?}");
    }

    #[test]
    fn a_part_pushed_out_of_view_is_hidden_not_gone() {
        // Pushed back behind the wall: the goal frame shows the wall where
        // the panel would be, in front of it, so none of the goal's points
        // arrive; the way is deeper along the rays through the panel.
        let near = Vector3::new(0.0, 0.0, 1.2);
        let c = change(&scene(0.0, 1.2).view(), &scene(0.0, 2.5).view(), near).unwrap();
        assert!(c.hidden && c.arriving < MIN_CHANGED, "{c:?}");
        assert!((c.shift - Vector3::z()).norm() < 0.05, "{c:?}");
        // In view, the same move is read from the points.
        let seen = change(&scene(0.0, 1.2).view(), &scene(0.35, 1.6).view(), near).unwrap();
        assert!(
            !seen.hidden && seen.shift.x > 0.1 && seen.shift.z > 0.1,
            "{seen:?}"
        );
    }
}
