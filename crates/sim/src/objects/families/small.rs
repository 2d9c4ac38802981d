//! Recipes for small objects: lids, hinged tops, switches, handles and knobs.
#![allow(
    clippy::indexing_slicing,
    reason = "the generator indexes parts it created itself; no input reaches it"
)]
use super::super::builder::Parts;
use super::parts::{Drawer, Lid, R, body, bx, color, u, v};
use crate::model::JointKind::{Prismatic, Revolute};
use rand::Rng;

pub(super) fn box_lid_family(p: &mut Parts, rng: &mut R, dims: (f32, f32, f32), upper: (f32, f32)) {
    let (w, d, h) = dims;
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, w, d, h, 0.0, cb);
    Lid {
        top: h,
        x: (-w / 2.0, w / 2.0),
        y: (-d / 2.0, d / 2.0),
        upper: u(rng, upper.0, upper.1),
        color: cp,
        thick: 0.03,
    }
    .attach(p, b);
}

pub(super) fn laptop(p: &mut Parts, rng: &mut R) {
    let (w, d, t) = (u(rng, 0.5, 0.7), u(rng, 0.35, 0.48), u(rng, 0.03, 0.045));
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, w, d, t, 0.0, cb);
    let s = p.part(
        b,
        Revolute,
        v(0.0, d / 2.0, t + 0.01),
        v(-1.0, 0.0, 0.0),
        (0.0, u(rng, 1.7, 2.2)),
        &[bx(v(0.0, 0.0, t + 0.01), v(w, d, 0.02))],
        cp,
    );
    let _ = s;
}

pub(super) fn phone(p: &mut Parts, rng: &mut R) {
    let (w, d, t) = (u(rng, 0.28, 0.36), u(rng, 0.45, 0.6), 0.05);
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, w, d, t, 0.0, cb);
    p.part(
        b,
        Revolute,
        v(0.0, d / 2.0, t + 0.02),
        v(-1.0, 0.0, 0.0),
        (0.0, u(rng, 2.4, 2.8)),
        &[bx(v(0.0, 0.0, t + 0.02), v(w, d, 0.04))],
        cp,
    );
}

pub(super) fn stapler(p: &mut Parts, rng: &mut R) {
    let (w, l) = (u(rng, 0.1, 0.15), u(rng, 0.5, 0.65));
    let (cb, cp) = (color(rng), color(rng));
    let b = p.base(
        &[
            bx(v(0.0, 0.0, 0.02), v(w * 1.2, l, 0.04)),
            bx(v(0.0, l / 2.0 - 0.05, 0.09), v(w, 0.08, 0.1)),
        ],
        cb,
    );
    p.part(
        b,
        Revolute,
        v(0.0, l / 2.0 - 0.05, 0.14),
        v(-1.0, 0.0, 0.0),
        (0.0, u(rng, 0.7, 1.1)),
        &[bx(v(0.0, -0.02, 0.16), v(w, l * 0.95, 0.06))],
        cp,
    );
}

pub(super) fn trash_can(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.38, 0.5), u(rng, 0.38, 0.5), u(rng, 0.55, 0.8));
    let (cb, cp) = (color(rng), color(rng));
    if rng.random_bool(0.5) {
        let b = body(p, w, d, h, 0.0, cb);
        Lid {
            top: h,
            x: (-w / 2.0, w / 2.0),
            y: (-d / 2.0, d / 2.0),
            upper: u(rng, 1.3, 1.8),
            color: cp,
            thick: 0.03,
        }
        .attach(p, b);
    } else {
        // Pull-out bin in a cabinet.
        let b = body(p, w, d, h, 0.0, cb);
        Drawer {
            y_face: -d / 2.0,
            x: (-w / 2.0 + 0.02, w / 2.0 - 0.02),
            z: (0.04, h - 0.04),
            depth: d * 0.85,
            range: u(rng, 0.3, 0.36).min(d * 0.85),
            color: cp,
        }
        .attach(p, b);
    }
}

pub(super) fn switch(p: &mut Parts, rng: &mut R) {
    let (w, h, d, z0) = (
        u(rng, 0.4, 0.6),
        u(rng, 0.45, 0.6),
        0.05,
        u(rng, 0.15, 0.35),
    );
    let (cb, cp) = (color(rng), color(rng));
    let b = p.base(
        &[
            bx(v(0.0, 0.0, z0 + h / 2.0), v(w, d, h)),
            bx(v(0.0, 0.0, z0 / 2.0), v(0.1, 0.1, z0)),
        ],
        cb,
    );
    let n = rng.random_range(1..=2);
    let slider = rng.random_bool(0.4);
    for k in 0..n {
        let x = if n == 1 {
            0.0
        } else {
            (k as f32 - 0.5) * w * 0.5
        };
        if slider {
            // A slider knob in a vertical slot.
            let range = (h - 0.15).min(0.35);
            let zk = z0 + 0.075;
            p.part(
                b,
                Prismatic,
                v(x, -d / 2.0 - 0.03, zk),
                v(0.0, 0.0, 1.0),
                (0.0, range),
                &[bx(v(x, -d / 2.0 - 0.03, zk), v(0.08, 0.06, 0.08))],
                cp,
            );
        } else {
            // A toggle lever pivoting about a horizontal axis.
            let zc = z0 + h / 2.0;
            let len = u(rng, 0.18, 0.25);
            p.part(
                b,
                Revolute,
                v(x, -d / 2.0, zc),
                v(1.0, 0.0, 0.0),
                (-0.7, 0.7),
                &[bx(v(x, -d / 2.0 - len / 2.0, zc), v(0.06, len, 0.05))],
                cp,
            );
        }
    }
}

pub(super) fn kettle(p: &mut Parts, rng: &mut R) {
    let (w, h) = (u(rng, 0.3, 0.4), u(rng, 0.35, 0.5));
    let (cb, cp) = (color(rng), color(rng));
    let b = p.base(
        &[
            bx(v(0.0, 0.0, h / 2.0), v(w, w, h)),
            bx(v(0.0, w / 2.0 + 0.04, h * 0.55), v(0.05, 0.08, h * 0.6)),
        ],
        cb,
    );
    let lw = w * 0.7;
    if rng.random_bool(0.5) {
        Lid {
            top: h,
            x: (-lw / 2.0, lw / 2.0),
            y: (-lw / 2.0, lw / 2.0),
            upper: u(rng, 1.3, 1.8),
            color: cp,
            thick: 0.03,
        }
        .attach(p, b);
    } else {
        p.part(
            b,
            Prismatic,
            v(0.0, 0.0, h + 0.02),
            v(0.0, 0.0, 1.0),
            (0.0, u(rng, 0.3, 0.4)),
            &[
                bx(v(0.0, 0.0, h + 0.02), v(lw, lw, 0.04)),
                bx(v(0.0, 0.0, h + 0.06), v(0.08, 0.08, 0.04)),
            ],
            cp,
        );
    }
}

pub(super) fn kitchen_pot(p: &mut Parts, rng: &mut R) {
    let (w, h) = (u(rng, 0.4, 0.55), u(rng, 0.22, 0.32));
    let (cb, cp) = (color(rng), color(rng));
    let b = p.base(
        &[
            bx(v(0.0, 0.0, h / 2.0), v(w, w, h)),
            bx(v(-w / 2.0 - 0.04, 0.0, h * 0.8), v(0.08, 0.04, 0.03)),
            bx(v(w / 2.0 + 0.04, 0.0, h * 0.8), v(0.08, 0.04, 0.03)),
        ],
        cb,
    );
    p.part(
        b,
        Prismatic,
        v(0.0, 0.0, h + 0.015),
        v(0.0, 0.0, 1.0),
        (0.0, u(rng, 0.3, 0.45)),
        &[
            bx(v(0.0, 0.0, h + 0.015), v(w + 0.02, w + 0.02, 0.03)),
            bx(v(0.0, 0.0, h + 0.05), v(0.1, 0.04, 0.04)),
        ],
        cp,
    );
}

pub(super) fn bucket(p: &mut Parts, rng: &mut R) {
    let (w, h) = (u(rng, 0.35, 0.45), u(rng, 0.35, 0.45));
    let (cb, cp) = (color(rng), color(rng));
    let b = p.base(&[bx(v(0.0, 0.0, h / 2.0), v(w, w, h))], cb);
    let r = u(rng, 0.22, 0.3);
    let t = 0.03;
    p.part(
        b,
        Revolute,
        v(0.0, 0.0, h * 0.85),
        v(1.0, 0.0, 0.0),
        (-1.4, 1.4),
        &[
            bx(v(-w / 2.0 - t, 0.0, h * 0.85 + r / 2.0), v(t, t, r)),
            bx(v(w / 2.0 + t, 0.0, h * 0.85 + r / 2.0), v(t, t, r)),
            bx(v(0.0, 0.0, h * 0.85 + r), v(w + 3.0 * t, 0.05, 0.04)),
        ],
        cp,
    );
}

/// The Toy: a knob travelling along a curved track in a panel. Training
/// instances curve one way (track centre below the knob), test instances the
/// other (centre above), so the direction must turn at every step.
pub(super) fn toy(p: &mut Parts, rng: &mut R, test: bool) {
    let (w, h, d, z0) = (u(rng, 0.75, 0.9), u(rng, 0.55, 0.65), 0.06, 0.15);
    let (cb, cp) = (color(rng), color(rng));
    let r = u(rng, 0.22, 0.28);
    let sign = if test { -1.0 } else { 1.0 };
    let knob_z = z0 + h / 2.0 + sign * r * 0.35;
    let centre = v(0.0, -d / 2.0, knob_z - sign * r);
    let range = 1.1;
    let mut boxes = vec![
        bx(v(0.0, 0.0, z0 + h / 2.0), v(w, d, h)),
        bx(v(0.0, 0.0, z0 / 2.0), v(0.15, 0.1, z0)),
    ];
    // The track, drawn as short segments along the arc.
    let n = 16;
    for k in 0..=n {
        let a = -range + 2.0 * range * k as f32 / n as f32;
        let pos = centre + v(r * a.sin(), -0.005, sign * r * a.cos());
        boxes.push(bx(pos, v(0.03, 0.01, 0.03)));
    }
    let b = p.base(&boxes, cb);
    let knob = centre + v(0.0, -0.04, sign * r);
    p.part(
        b,
        Revolute,
        centre,
        v(0.0, sign, 0.0),
        (-range, range),
        &[bx(knob, v(0.07, 0.07, 0.07))],
        cp,
    );
}
