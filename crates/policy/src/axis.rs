//! Joint-axis inference from the executed directions (paper, "Inferring
//! objects' articulation structure"): prismatic = mean direction; revolute =
//! the normal of the common action plane (L1 fit), positioned by voting.
#![allow(
    clippy::indexing_slicing,
    reason = "callers pass at least one direction and point (checked at entry)"
)]
use nalgebra::{Matrix3, Vector3};

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
/// A joint inferred from the moves that moved the part (world frame).
pub enum JointEstimate {
    /// A slide.
    Prismatic {
        /// Unit direction of the slide.
        axis: [f32; 3],
    },
    /// A hinge.
    Revolute {
        /// Unit direction of the hinge axis.
        axis: [f32; 3],
        /// A point on the hinge axis.
        point: [f32; 3],
    },
}

impl JointEstimate {
    /// The unit direction the joint moves a point at `p` (world frame), up
    /// to sign: the axis for a slide, the tangent of the circle about the
    /// axis for a hinge. None on a hinge's axis.
    pub fn motion_at(&self, p: Vector3<f32>) -> Option<Vector3<f32>> {
        let v = match self {
            Self::Prismatic { axis } => Vector3::from(*axis),
            Self::Revolute { axis, point } => {
                Vector3::from(*axis).cross(&(p - Vector3::from(*point)))
            }
        };
        (v.norm() > 1e-6 && v.iter().all(|x| x.is_finite())).then(|| v.normalize())
    }

    /// Whether every number is finite and the axis has a direction: what a
    /// joint read back from a file must be before a policy uses it.
    pub fn is_usable(&self) -> bool {
        let (axis, point) = match self {
            Self::Prismatic { axis } => (axis, [0.0; 3]),
            Self::Revolute { axis, point } => (axis, *point),
        };
        axis.iter().chain(&point).all(|v| v.is_finite()) && Vector3::from(*axis).norm() > 1e-6
    }

    /// The way on for a point that went `motion` over its last move to
    /// reach `point` (world frame): the last move carried along with the
    /// part. On a slide that is the same way; on a hinge, the last chord
    /// turned about the axis by the angle it spanned, the next chord of
    /// the same length (a move along the last chord leaves the circle,
    /// and on a short lever stalls at once). Where the motion does not fit
    /// the hinge (it changed its distance from the axis by more than
    /// [`ARC_FIT`] of its length, or runs along the axis), the joint is
    /// read wrong, and the way is the motion's own. None for no motion.
    pub fn onward(&self, point: Vector3<f32>, motion: Vector3<f32>) -> Option<Vector3<f32>> {
        let way = motion.try_normalize(1e-6)?;
        let Self::Revolute {
            axis,
            point: on_axis,
        } = self
        else {
            return Some(way);
        };
        let Some(a) = nalgebra::Unit::try_new(Vector3::from(*axis), 1e-6) else {
            return Some(way);
        };
        let from_axis = |p: Vector3<f32>| {
            let v = p - Vector3::from(*on_axis);
            v - a.into_inner() * a.dot(&v)
        };
        let (before, now) = (from_axis(point - motion), from_axis(point));
        let fits = (now.norm() - before.norm()).abs() <= ARC_FIT * motion.norm()
            && a.dot(&way).abs() <= ARC_FIT_ALONG_AXIS
            && before.norm().min(now.norm()) > 1e-3;
        if !fits {
            return Some(way);
        }
        let spanned = a.dot(&before.cross(&now)).atan2(before.dot(&now));
        let next =
            nalgebra::Rotation3::from_axis_angle(&a, spanned.clamp(-MAX_TURN_RAD, MAX_TURN_RAD))
                * way;
        Some(if next.iter().all(|x| x.is_finite()) {
            next
        } else {
            way
        })
    }
}

/// [`JointEstimate::onward`]: a motion that changed its distance from a
/// hinge's axis by more than this share of its length is not on the
/// hinge's circle.
pub const ARC_FIT: f32 = 0.3;

/// [`JointEstimate::onward`]: a motion whose cosine with a hinge's axis is
/// above this is not about the axis.
pub const ARC_FIT_ALONG_AXIS: f32 = 0.5;

/// [`JointEstimate::onward`] turns a move at most this far from the last
/// (the chords of a 0.2 m lever, the shortest, turn 0.9 rad).
pub const MAX_TURN_RAD: f32 = 1.0;

/// Angle in degrees between two axes, ignoring their sign.
pub fn axis_angle_deg(a: &Vector3<f32>, b: &Vector3<f32>) -> f32 {
    (a.normalize().dot(&b.normalize()).abs().clamp(0.0, 1.0))
        .acos()
        .to_degrees()
}

/// min over unit n of sum |n . a_t|, by iteratively reweighted least squares
/// starting from the least-squares plane.
pub fn l1_plane_normal(directions: &[Vector3<f32>]) -> Option<Vector3<f32>> {
    let mut w = vec![1.0f32; directions.len()];
    let mut n = None;
    for _ in 0..30 {
        let mut m = Matrix3::zeros();
        for (d, wi) in directions.iter().zip(&w) {
            m += *wi * d * d.transpose();
        }
        let eig = m.symmetric_eigen();
        let (k, _) = eig
            .eigenvalues
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))?;
        let cand: Vector3<f32> = eig.eigenvectors.column(k).into_owned().normalize();
        for (d, wi) in directions.iter().zip(w.iter_mut()) {
            *wi = 1.0 / cand.dot(d).abs().max(1e-3);
        }
        n = Some(cand);
    }
    n
}

/// The mean of unit `directions` after flipping each to the side of the
/// first: a prismatic joint is pushed and pulled along one line.
fn aligned_mean(directions: &[Vector3<f32>]) -> Vector3<f32> {
    let first = directions[0];
    let sum: Vector3<f32> = directions
        .iter()
        .map(|d| if d.dot(&first) < 0.0 { -d } else { *d })
        .sum();
    sum / directions.len() as f32
}

/// The paper's axis for a joint of known kind, as its evaluation computes
/// it: the mean action direction for a prismatic joint, the normal of the
/// common action plane for a revolute one. None with fewer than 2 directions.
pub fn axis_of_known_kind(directions: &[Vector3<f32>], prismatic: bool) -> Option<Vector3<f32>> {
    if directions.len() < 2 {
        return None;
    }
    if prismatic {
        let mean = aligned_mean(directions);
        (mean.norm() > 1e-6).then(|| mean.normalize())
    } else {
        l1_plane_normal(directions)
    }
}

/// Infers the joint from executed unit `directions` and the gripper positions
/// `points` where each was executed. Returns None with fewer than 2 actions.
pub fn infer_joint(directions: &[Vector3<f32>], points: &[Vector3<f32>]) -> Option<JointEstimate> {
    if directions.len() < 2 || directions.len() != points.len() {
        return None;
    }
    let mean = aligned_mean(directions);
    if mean.norm() > 0.97 {
        let a = mean.normalize();
        return Some(JointEstimate::Prismatic {
            axis: [a.x, a.y, a.z],
        });
    }
    let n = l1_plane_normal(directions)?;
    // Each action is tangent to a circle about the axis: the axis meets the
    // plane on the line through the action point, perpendicular to the action.
    // Intersect consecutive lines (in the plane) and take the median.
    let project = |p: &Vector3<f32>| p - n * n.dot(p);
    let lines: Vec<(Vector3<f32>, Vector3<f32>)> = points
        .iter()
        .zip(directions)
        .map(|(p, d)| (project(p), n.cross(&project(d)).normalize()))
        .collect();
    let mut votes: Vec<Vector3<f32>> = Vec::new();
    for i in 0..lines.len() {
        for j in i + 1..lines.len() {
            let ((p1, u1), (p2, u2)) = (lines[i], lines[j]);
            // p1 + s u1 = p2 + t u2, least squares in 3-D (all vectors in the plane).
            let m = nalgebra::Matrix3x2::from_columns(&[u1, -u2]);
            let Some(st) = (m.transpose() * m)
                .try_inverse()
                .map(|inv| inv * m.transpose() * (p2 - p1))
            else {
                continue;
            };
            let x = p1 + u1 * st[0];
            if x.iter().all(|v| v.is_finite()) && (x - p1).norm() < 5.0 {
                votes.push(x);
            }
        }
    }
    if votes.is_empty() {
        return None;
    }
    let median = |k: usize| {
        let mut v: Vec<f32> = votes.iter().map(|x| x[k]).collect();
        v.sort_by(f32::total_cmp);
        v[v.len() / 2]
    };
    let c = Vector3::new(median(0), median(1), median(2)) + n * n.dot(&points[0]);
    Some(JointEstimate::Revolute {
        axis: [n.x, n.y, n.z],
        point: [c.x, c.y, c.z],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_door_hinge_from_tangent_pulls() {
        let axis = Vector3::new(0.1, 0.2, 1.0).normalize();
        let centre = Vector3::new(0.3, -0.4, 0.5);
        let u = axis.cross(&Vector3::x()).normalize();
        let v = axis.cross(&u);
        let (mut dirs, mut pts) = (Vec::new(), Vec::new());
        for k in 0..6 {
            let a = k as f32 * 0.25;
            let p = centre + 0.8 * (u * a.cos() + v * a.sin()) + axis * 0.1;
            let t = axis.cross(&(p - centre)).normalize();
            dirs.push(t);
            pts.push(p);
        }
        let Some(JointEstimate::Revolute { axis: a, point }) = infer_joint(&dirs, &pts) else {
            panic!("not revolute")
        };
        assert!(axis_angle_deg(&Vector3::from(a), &axis) < 1.0);
        let d = Vector3::from(point) - centre;
        assert!(
            (d - axis * axis.dot(&d)).norm() < 0.01,
            "axis position off by {}",
            d.norm()
        );
    }

    #[test]
    fn a_joint_moves_a_point_along_its_slide_or_its_circle() {
        let slide = JointEstimate::Prismatic {
            axis: [0.0, 0.0, 1.0],
        };
        assert_eq!(
            slide.motion_at(Vector3::new(3.0, 1.0, 0.0)),
            Some(Vector3::z())
        );
        let hinge = JointEstimate::Revolute {
            axis: [0.0, 0.0, 1.0],
            point: [1.0, 0.0, 0.0],
        };
        let t = hinge.motion_at(Vector3::new(1.0, 2.0, 5.0)).unwrap();
        assert!((t - Vector3::new(-1.0, 0.0, 0.0)).norm() < 1e-6, "{t:?}");
        assert_eq!(
            hinge.motion_at(Vector3::new(1.0, 0.0, 3.0)),
            None,
            "on the axis"
        );
    }

    #[test]
    fn onward_on_a_hinge_is_the_last_chord_turned_by_the_angle_it_spanned() {
        let hinge = JointEstimate::Revolute {
            axis: [0.0, 0.0, 1.0],
            point: [0.2, -0.1, 0.0],
        };
        let at = |t: f32| Vector3::new(0.2 + 0.3 * t.cos(), -0.1 + 0.3 * t.sin(), 0.4);
        for (from, to) in [(0.0, 0.5), (0.5, 0.0), (1.0, 1.2), (-0.3, -1.1)] {
            let next = hinge.onward(at(to), at(to) - at(from)).unwrap();
            let want = (at(2.0 * to - from) - at(to)).normalize();
            assert!(
                (next - want).norm() < 1e-4,
                "{from} -> {to}: {next:?} vs {want:?}"
            );
        }
    }

    #[test]
    fn onward_keeps_the_motion_on_a_slide_and_off_a_hinge_read_wrong() {
        let m = Vector3::new(0.1, 0.02, 0.03);
        let slide = JointEstimate::Prismatic {
            axis: [1.0, 0.0, 0.0],
        };
        assert_eq!(slide.onward(Vector3::zeros(), m), Some(m.normalize()));
        let hinge = JointEstimate::Revolute {
            axis: [0.0, 0.0, 1.0],
            point: [0.0, 0.0, 0.0],
        };
        // Straight away from the axis: not on its circle.
        let out = Vector3::new(0.1, 0.0, 0.0);
        let p = Vector3::new(0.5, 0.0, 0.0);
        assert_eq!(hinge.onward(p, out), Some(Vector3::x()));
        // Along the axis.
        let up = Vector3::new(0.0, 0.02, 0.1);
        let p = Vector3::new(0.0, 0.5, 0.3);
        assert_eq!(hinge.onward(p, up), Some(up.normalize()));
        assert_eq!(hinge.onward(p, Vector3::zeros()), None);
    }

    #[test]
    fn onward_turns_at_most_max_turn_rad() {
        let hinge = JointEstimate::Revolute {
            axis: [0.0, 0.0, 1.0],
            point: [0.0, 0.0, 0.0],
        };
        // Half a turn about an axis read 5 cm away.
        let (p, m) = (Vector3::new(-0.05, 0.0, 0.0), Vector3::new(-0.1, 0.0, 0.0));
        let next = hinge.onward(p, m).unwrap();
        let angle = next.dot(&m.normalize()).clamp(-1.0, 1.0).acos();
        assert!((angle - MAX_TURN_RAD).abs() < 1e-4, "{angle}");
    }

    #[test]
    fn a_joint_read_back_is_usable_only_with_an_axis_and_finite_numbers() {
        let hinge = |axis: [f32; 3], point: [f32; 3]| JointEstimate::Revolute { axis, point };
        assert!(hinge([0.0, 0.0, 1.0], [1.0, 2.0, 3.0]).is_usable());
        assert!(!hinge([0.0, 0.0, 0.0], [1.0, 2.0, 3.0]).is_usable());
        assert!(!hinge([0.0, 0.0, 1.0], [f32::NAN, 2.0, 3.0]).is_usable());
        let slide = |axis: [f32; 3]| JointEstimate::Prismatic { axis };
        assert!(slide([0.0, 1.0, 0.0]).is_usable());
        assert!(!slide([f32::INFINITY, 1.0, 0.0]).is_usable());
    }

    #[test]
    fn prismatic_is_the_mean_direction() {
        let d = Vector3::new(0.0, -1.0, 0.1).normalize();
        let dirs = vec![d, d, -d, d];
        let pts = vec![Vector3::zeros(); 4];
        let Some(JointEstimate::Prismatic { axis }) = infer_joint(&dirs, &pts) else {
            panic!()
        };
        assert!(axis_angle_deg(&Vector3::from(axis), &d) < 0.1);
    }
}
