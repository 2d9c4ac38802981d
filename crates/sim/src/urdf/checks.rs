//! Every number urdf-rs parsed, checked before the model is built from it.
use super::{MAX_LIMIT, MAX_MESH_SCALE, MIN_MESH_SCALE, urdf_err};
use crate::error::Result;
use std::path::Path;

/// Every number the model keeps must be finite: a NaN passes the XML reader
/// and poisons the physics silently (the joint comes back as NaN with exit 0).
/// They are checked as the f32 the physics stores: `1e39` is finite in the
/// file and infinite after conversion. Sizes, inertias and colours must also
/// be in range: a negative inertia freezes a joint, a negative size or scale
/// turns a mesh inside out.
#[expect(
    clippy::too_many_lines,
    reason = "a flat list of checks, one per URDF field, each naming its element"
)]
pub(super) fn check_numbers(robot: &urdf_rs::Robot, path: &Path) -> Result<()> {
    let finite = |v: f64| (v as f32).is_finite();
    let bad = |what: String, values: &[f64]| -> Result<()> {
        if values.iter().all(|v| finite(*v)) {
            Ok(())
        } else {
            Err(urdf_err(
                path,
                format!("{what} must be finite numbers within f32 range, found {values:?}"),
            ))
        }
    };
    let at_least = |what: String, values: &[f64], min: f64, strict: bool| -> Result<()> {
        bad(what.clone(), values)?;
        if values
            .iter()
            .all(|v| if strict { *v > min } else { *v >= min })
        {
            Ok(())
        } else {
            let rel = if strict { ">" } else { ">=" };
            Err(urdf_err(
                path,
                format!("{what} must be {rel} {min}, found {values:?}"),
            ))
        }
    };
    let origin = |what: String, o: &urdf_rs::Pose| -> Result<()> {
        bad(
            format!("{what} <origin xyz/rpy>"),
            &[o.xyz.0, o.rpy.0].concat(),
        )
    };
    let geometry = |what: String, g: &urdf_rs::Geometry| -> Result<()> {
        match g {
            urdf_rs::Geometry::Box { size } => {
                at_least(format!("{what} <box size>"), &size.0, 0.0, false)
            }
            urdf_rs::Geometry::Cylinder { radius, length }
            | urdf_rs::Geometry::Capsule { radius, length } => at_least(
                format!("{what} radius/length"),
                &[*radius, *length],
                0.0,
                false,
            ),
            urdf_rs::Geometry::Sphere { radius } => {
                at_least(format!("{what} <sphere radius>"), &[*radius], 0.0, false)
            }
            urdf_rs::Geometry::Mesh { scale, .. } => match scale {
                Some(s) => {
                    at_least(format!("{what} <mesh scale>"), &s.0, 0.0, true)?;
                    // 1e-300 is positive in the file and zero as f32: a flat mesh.
                    if s.0
                        .iter()
                        .all(|v| (MIN_MESH_SCALE..=MAX_MESH_SCALE).contains(v))
                    {
                        Ok(())
                    } else {
                        Err(urdf_err(
                            path,
                            format!(
                                "{what} <mesh scale> must be within [{MIN_MESH_SCALE:e}, {MAX_MESH_SCALE:e}], found {:?}",
                                s.0
                            ),
                        ))
                    }
                }
                None => Ok(()),
            },
        }
    };
    let color = |what: String, m: &Option<urdf_rs::Material>| -> Result<()> {
        match m.as_ref().and_then(|m| m.color.as_ref()) {
            Some(c) if !c.rgba.0.iter().all(|v| (0.0..=1.0).contains(v)) => Err(urdf_err(
                path,
                format!(
                    "{what} <color rgba> must be 4 numbers in [0, 1], found {:?}",
                    c.rgba.0
                ),
            )),
            _ => Ok(()),
        }
    };
    for m in &robot.materials {
        color(format!("material `{}`", m.name), &Some(m.clone()))?;
    }
    for l in &robot.links {
        let i = &l.inertial;
        origin(format!("link `{}` <inertial>", l.name), &i.origin)?;
        let t = &i.inertia;
        bad(
            format!("link `{}` <inertia>", l.name),
            &[t.ixx, t.ixy, t.ixz, t.iyy, t.iyz, t.izz],
        )?;
        at_least(
            format!("link `{}` <inertia> ixx/iyy/izz", l.name),
            &[t.ixx, t.iyy, t.izz],
            0.0,
            false,
        )?;
        // A body's inertia tensor has non-negative principal moments that obey the
        // triangle inequality (i1 + i2 - i3 = 2 * integral of r3^2 dm >= 0); one
        // that breaks either is no rigid body, and the solver turns it into NaN.
        let moments = principal_moments([
            [t.ixx, t.ixy, t.ixz],
            [t.ixy, t.iyy, t.iyz],
            [t.ixz, t.iyz, t.izz],
        ]);
        let [a, b, c] = moments;
        let slack = 1e-6 * (a.abs() + b.abs() + c.abs());
        if !moments.iter().all(|m| m.is_finite() && *m >= -slack)
            || a + b < c - slack
            || b + c < a - slack
            || a + c < b - slack
        {
            return Err(urdf_err(
                path,
                format!(
                    "link `{}` <inertia> has principal moments {moments:?}: they must be non-negative, each at most the sum of the other two, or no rigid body has them",
                    l.name
                ),
            ));
        }
        for v in &l.visual {
            let what = format!("link `{}` <visual>", l.name);
            origin(what.clone(), &v.origin)?;
            geometry(what.clone(), &v.geometry)?;
            color(what, &v.material)?;
        }
        for c in &l.collision {
            let what = format!("link `{}` <collision>", l.name);
            origin(what.clone(), &c.origin)?;
            geometry(what, &c.geometry)?;
        }
    }
    for j in &robot.joints {
        origin(format!("joint `{}`", j.name), &j.origin)?;
        // Checked before normalising: `1e39 0 0` is a direction in f64 but
        // overflows the f32 the file's numbers are meant as.
        bad(format!("joint `{}` <axis xyz>", j.name), &j.axis.xyz.0)?;
        let l = &j.limit;
        bad(
            format!("joint `{}` <limit> lower/upper", j.name),
            &[l.lower, l.upper],
        )?;
        let limited = matches!(
            j.joint_type,
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Prismatic
        );
        if limited && (l.lower.abs() > MAX_LIMIT || l.upper.abs() > MAX_LIMIT) {
            return Err(urdf_err(
                path,
                format!(
                    "joint `{}` <limit> lower/upper must be within ±{MAX_LIMIT} (m or rad), found lower={} upper={}; a joint without limits is `continuous`",
                    j.name, l.lower, l.upper
                ),
            ));
        }
        at_least(
            format!("joint `{}` <limit> effort/velocity", j.name),
            &[l.effort, l.velocity],
            0.0,
            false,
        )?;
    }
    Ok(())
}

/// Eigenvalues of a symmetric 3x3 matrix (closed form, Smith 1961).
pub(super) fn principal_moments(m: [[f64; 3]; 3]) -> [f64; 3] {
    let [[a, d, e], [_, b, f], [_, _, c]] = m;
    let off = d * d + e * e + f * f;
    if off == 0.0 {
        return [a, b, c];
    }
    let q = (a + b + c) / 3.0;
    let p = (((a - q).powi(2) + (b - q).powi(2) + (c - q).powi(2) + 2.0 * off) / 6.0).sqrt();
    if !(p.is_finite() && p > 0.0) {
        return [f64::NAN; 3];
    }
    let n = |x: f64| x / p;
    let (a2, b2, c2, d2, e2, f2) = (n(a - q), n(b - q), n(c - q), n(d), n(e), n(f));
    let det = a2 * (b2 * c2 - f2 * f2) - d2 * (d2 * c2 - f2 * e2) + e2 * (d2 * f2 - b2 * e2);
    let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
    let third = 2.0 * std::f64::consts::PI / 3.0;
    let l1 = q + 2.0 * p * phi.cos();
    let l3 = q + 2.0 * p * (phi + third).cos();
    [l1, 3.0 * q - l1 - l3, l3]
}
