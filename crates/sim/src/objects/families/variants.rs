//! Mechanisms PartNet-Mobility's training categories have and the paper's
//! recipes above leave out: flaps hinged at the top or the bottom edge,
//! swinging bail handles, a flap hinged on a lid. Only training instances draw
//! them (see `families::build`), so held-out instances and the test
//! categories keep the recipes every published figure was measured on.
#![allow(
    clippy::indexing_slicing,
    reason = "the generator indexes parts it created itself; no input reaches it"
)]
use super::super::builder::Parts;
use super::furniture::{WINDOW_FRAME, window_frame};
use super::parts::{Drawer, FlapDoor, HANDLE, Lid, R, T, body, bx, color, u, v};
use crate::model::JointKind::Revolute;
use rand::Rng;

/// A flap hinged at its top edge (a wall cabinet's flip-up door): its bottom
/// edge swings out toward -y and up to `upper` rad.
fn flip_up(
    p: &mut Parts,
    parent: usize,
    y_face: f32,
    x: (f32, f32),
    z: (f32, f32),
    upper: f32,
    c: [f32; 3],
) {
    let (x0, x1) = x;
    let (z0, z1) = z;
    let yc = y_face - T / 2.0;
    p.part(
        parent,
        Revolute,
        v((x0 + x1) / 2.0, yc, z1),
        v(-1.0, 0.0, 0.0),
        (0.0, upper),
        &[
            bx(
                v((x0 + x1) / 2.0, yc, (z0 + z1) / 2.0),
                v(x1 - x0, T, z1 - z0),
            ),
            bx(
                v((x0 + x1) / 2.0, y_face - T - HANDLE / 2.0, z0 + 0.05),
                v((x1 - x0) * 0.5, HANDLE, 0.025),
            ),
        ],
        c,
    );
}

/// StorageFurniture: a cabinet whose doors are flaps (a drop-front desk, a
/// flip-up wall cabinet), sometimes above a row of drawers.
pub(super) fn flap_cabinet(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.5, 0.9), u(rng, 0.35, 0.5), u(rng, 0.45, 1.0));
    let (cb, cp) = (color(rng), color(rng));
    let z0 = if rng.random_bool(0.3) {
        u(rng, 0.2, 0.4)
    } else {
        0.0
    };
    let b = body(p, w, d, h, z0, cb);
    let y = -d / 2.0;
    let (x0, x1) = (-w / 2.0 + 0.03, w / 2.0 - 0.03);
    let mut bottom = z0 + 0.03;
    if h > 0.7 && rng.random_bool(0.5) {
        let dh = 0.18_f32.min(h * 0.3);
        Drawer {
            y_face: y,
            x: (x0, x1),
            z: (bottom, bottom + dh - 0.02),
            depth: d * 0.85,
            range: u(rng, 0.25, 0.34).min(d * 0.85),
            color: cp,
        }
        .attach(p, b);
        bottom += dh;
    }
    let top = z0 + h - 0.03;
    let flaps = if top - bottom > 0.5 && rng.random_bool(0.5) {
        2
    } else {
        1
    };
    let step = (top - bottom) / flaps as f32;
    for k in 0..flaps {
        let z = (
            bottom + k as f32 * step + 0.01,
            bottom + (k + 1) as f32 * step - 0.01,
        );
        if rng.random_bool(0.5) {
            FlapDoor {
                y_face: y,
                x: (x0, x1),
                z,
                upper: u(rng, 1.2, 1.57),
                color: cp,
            }
            .attach(p, b);
        } else {
            flip_up(p, b, y, (x0, x1), z, u(rng, 1.2, 1.7), cp);
        }
    }
}

/// Window: a sash hinged at its top (awning) or bottom (hopper) edge,
/// opening toward the room (-y).
pub(super) fn hung_window(p: &mut Parts, rng: &mut R) {
    let (w, h, d, z0) = (u(rng, 0.6, 1.0), u(rng, 0.5, 0.9), 0.1, u(rng, 0.1, 0.35));
    let (cb, cp) = (color(rng), color(rng));
    let f = WINDOW_FRAME;
    let b = p.base(&window_frame(w, h, d, z0), cb);
    let x = (-w / 2.0 + f, w / 2.0 - f);
    let z = (z0 + f, z0 + h - f);
    if rng.random_bool(0.5) {
        FlapDoor {
            y_face: -d / 2.0,
            x,
            z,
            upper: u(rng, 0.6, 1.2),
            color: cp,
        }
        .attach(p, b);
    } else {
        flip_up(p, b, -d / 2.0, x, z, u(rng, 0.8, 1.4), cp);
    }
}

/// Kettle: a body with a bail handle swinging fore and aft over its top, and
/// sometimes a lid hinged at the back as well.
pub(super) fn bail_kettle(p: &mut Parts, rng: &mut R) {
    let (w, h) = (u(rng, 0.3, 0.42), u(rng, 0.3, 0.45));
    let (cb, cp) = (color(rng), color(rng));
    let b = p.base(&[bx(v(0.0, 0.0, h / 2.0), v(w, w, h))], cb);
    if rng.random_bool(0.5) {
        let lw = w * 0.6;
        Lid {
            top: h,
            x: (-lw / 2.0, lw / 2.0),
            y: (-lw / 2.0, lw / 2.0),
            upper: u(rng, 1.2, 1.6),
            color: color(rng),
            thick: 0.025,
        }
        .attach(p, b);
    }
    let (r, t) = (u(rng, 0.18, 0.28), 0.025);
    let pivot = h * u(rng, 0.85, 1.0);
    let reach = u(rng, 1.0, 1.5);
    p.part(
        b,
        Revolute,
        v(0.0, 0.0, pivot),
        v(1.0, 0.0, 0.0),
        (-reach, reach),
        &[
            bx(v(-w / 2.0 - t, 0.0, pivot + r / 2.0), v(t, t, r)),
            bx(v(w / 2.0 + t, 0.0, pivot + r / 2.0), v(t, t, r)),
            bx(v(0.0, 0.0, pivot + r), v(w + 3.0 * t, 0.04, 0.035)),
        ],
        cp,
    );
}

/// TrashCan: a lid hinged at the back with a small flap hinged on the lid
/// (a part whose parent is a moving part).
pub(super) fn flap_lid_can(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.38, 0.5), u(rng, 0.38, 0.5), u(rng, 0.5, 0.8));
    let (cb, cp, cf) = (color(rng), color(rng), color(rng));
    let b = body(p, w, d, h, 0.0, cb);
    let thick = 0.03;
    let lid = Lid {
        top: h,
        x: (-w / 2.0, w / 2.0),
        y: (-d / 2.0, d / 2.0),
        upper: u(rng, 1.2, 1.7),
        color: cp,
        thick,
    }
    .attach(p, b);
    // The flap covers the lid's front half, hinged across its middle; its
    // front edge lifts.
    let (fw, fd) = (w * 0.6, d * 0.4);
    let zc = h + thick + 0.01;
    p.part(
        lid,
        Revolute,
        v(0.0, 0.0, zc),
        v(-1.0, 0.0, 0.0),
        (0.0, u(rng, 0.8, 1.3)),
        &[
            bx(v(0.0, -fd / 2.0, zc), v(fw, fd, 0.02)),
            bx(v(0.0, -fd + 0.03, zc + 0.02), v(fw * 0.4, 0.03, 0.02)),
        ],
        cf,
    );
}
