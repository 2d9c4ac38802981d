//! Recipes for furniture and appliances: bodies with doors, drawers, flaps
//! and sashes on their front, and tables, doors and chairs.
#![allow(
    clippy::indexing_slicing,
    reason = "the generator indexes parts it created itself; no input reaches it"
)]
use super::super::builder::Parts;
use super::parts::{Door, Drawer, FlapDoor, Hinge, R, T, body, bx, color, u, v};
use crate::math::Vec3;
use crate::model::JointKind::{Prismatic, Revolute};
use rand::Rng;

pub(super) fn cabinet(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.5, 0.9), u(rng, 0.38, 0.5), u(rng, 0.55, 1.0));
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, w, d, h, 0.0, cb);
    let y = -d / 2.0;
    let layout = rng.random_range(0..3);
    let n_drawers = match layout {
        0 => 0,
        1 => rng.random_range(1..=3),
        _ => 1,
    };
    let drawer_h = if layout == 1 {
        (h - 0.06) / n_drawers as f32
    } else {
        0.18_f32.min(h * 0.3)
    };
    let mut top = h - 0.03;
    for _ in 0..n_drawers {
        Drawer {
            y_face: y,
            x: (-w / 2.0 + 0.03, w / 2.0 - 0.03),
            z: (top - drawer_h + 0.01, top - 0.01),
            depth: d * 0.85,
            range: u(rng, 0.3, 0.36).min(d * 0.85),
            color: cp,
        }
        .attach(p, b);
        top -= drawer_h;
    }
    if layout != 1 {
        let two = w > 0.6 && rng.random_bool(0.6);
        let (x0, x1) = (-w / 2.0 + 0.02, w / 2.0 - 0.02);
        let z = (0.05, top - 0.01);
        let upper = u(rng, 1.5, 2.0);
        if two {
            Door {
                y_face: y,
                x: (x0, -0.005),
                z,
                hinge: Hinge::Left,
                upper,
                color: cp,
                thick: T,
            }
            .attach(p, b);
            Door {
                y_face: y,
                x: (0.005, x1),
                z,
                hinge: Hinge::Right,
                upper,
                color: cp,
                thick: T,
            }
            .attach(p, b);
        } else {
            Door {
                y_face: y,
                x: (x0, x1),
                z,
                hinge: Hinge::left_if(rng.random_bool(0.5)),
                upper,
                color: cp,
                thick: T,
            }
            .attach(p, b);
        }
    }
}

pub(super) fn refrigerator(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.5, 0.7), u(rng, 0.45, 0.6), u(rng, 0.95, 1.25));
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, w, d, h, 0.0, cb);
    let (x0, x1, y) = (-w / 2.0 + 0.01, w / 2.0 - 0.01, -d / 2.0);
    let upper = u(rng, 1.4, 2.0);
    match rng.random_range(0..3) {
        0 => {
            Door {
                y_face: y,
                x: (x0, x1),
                z: (0.04, h - 0.02),
                hinge: Hinge::left_if(rng.random_bool(0.5)),
                upper,
                color: cp,
                thick: 0.04,
            }
            .attach(p, b);
        }
        1 => {
            let split = h * u(rng, 0.6, 0.7);
            let left = rng.random_bool(0.5);
            Door {
                y_face: y,
                x: (x0, x1),
                z: (0.04, split - 0.01),
                hinge: Hinge::left_if(left),
                upper,
                color: cp,
                thick: 0.04,
            }
            .attach(p, b);
            Door {
                y_face: y,
                x: (x0, x1),
                z: (split + 0.01, h - 0.02),
                hinge: Hinge::left_if(left),
                upper,
                color: cp,
                thick: 0.04,
            }
            .attach(p, b);
        }
        _ => {
            Door {
                y_face: y,
                x: (x0, -0.005),
                z: (0.04, h - 0.02),
                hinge: Hinge::Left,
                upper,
                color: cp,
                thick: 0.04,
            }
            .attach(p, b);
            Door {
                y_face: y,
                x: (0.005, x1),
                z: (0.04, h - 0.02),
                hinge: Hinge::Right,
                upper,
                color: cp,
                thick: 0.04,
            }
            .attach(p, b);
        }
    }
}

pub(super) fn microwave(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.55, 0.75), u(rng, 0.35, 0.45), u(rng, 0.32, 0.45));
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, w, d, h, 0.0, cb);
    let door_w = w * u(rng, 0.68, 0.78);
    Door {
        y_face: -d / 2.0,
        x: (-w / 2.0 + 0.01, -w / 2.0 + door_w),
        z: (0.02, h - 0.02),
        hinge: Hinge::Left,
        upper: u(rng, 1.4, 1.9),
        color: cp,
        thick: T,
    }
    .attach(p, b);
}

pub(super) fn safe(p: &mut Parts, rng: &mut R) {
    let s = u(rng, 0.4, 0.6);
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, s * u(rng, 0.9, 1.1), s, s * u(rng, 0.9, 1.3), 0.0, cb);
    let (w, h) = p.links[b]
        .mesh()
        .bounds()
        .map(|(lo, hi)| (hi.x - lo.x, hi.z - lo.z))
        .unwrap_or((s, s));
    Door {
        y_face: -s / 2.0,
        x: (-w / 2.0 + 0.03, w / 2.0 - 0.03),
        z: (0.03, h - 0.03),
        hinge: Hinge::left_if(rng.random_bool(0.5)),
        upper: u(rng, 1.5, 1.9),
        color: cp,
        thick: 0.05,
    }
    .attach(p, b);
}

pub(super) fn washing_machine(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.55, 0.65), u(rng, 0.5, 0.6), u(rng, 0.8, 0.9));
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, w, d, h, 0.0, cb);
    let door = w * u(rng, 0.6, 0.75);
    let zc = h * u(rng, 0.45, 0.55);
    Door {
        y_face: -d / 2.0,
        x: (-door / 2.0, door / 2.0),
        z: (zc - door / 2.0, zc + door / 2.0),
        hinge: Hinge::left_if(rng.random_bool(0.7)),
        upper: u(rng, 1.5, 1.9),
        color: cp,
        thick: 0.04,
    }
    .attach(p, b);
}

pub(super) fn oven(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.55, 0.7), u(rng, 0.5, 0.6), u(rng, 0.75, 0.9));
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, w, d, h, 0.0, cb);
    FlapDoor {
        y_face: -d / 2.0,
        x: (-w / 2.0 + 0.03, w / 2.0 - 0.03),
        z: (0.08, h * u(rng, 0.7, 0.8)),
        upper: u(rng, 1.35, 1.57),
        color: cp,
    }
    .attach(p, b);
}

pub(super) fn dishwasher(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.55, 0.65), u(rng, 0.5, 0.6), u(rng, 0.8, 0.9));
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, w, d, h, 0.0, cb);
    FlapDoor {
        y_face: -d / 2.0,
        x: (-w / 2.0 + 0.01, w / 2.0 - 0.01),
        z: (0.06, h - 0.02),
        upper: u(rng, 1.4, 1.57),
        color: cp,
    }
    .attach(p, b);
    // A rack behind the door: reachable once the door is open.
    let racks = rng.random_range(1..=2);
    for k in 0..racks {
        let z = 0.15 + k as f32 * h * 0.4;
        p.part(
            b,
            Prismatic,
            v(0.0, -d / 2.0 + 0.06, z),
            v(0.0, -1.0, 0.0),
            (0.0, d * 0.75),
            &[
                bx(v(0.0, -d / 2.0 + d * 0.4, z), v(w * 0.8, d * 0.7, 0.04)),
                bx(v(0.0, -d / 2.0 + 0.06, z + 0.05), v(w * 0.8, 0.02, 0.1)),
            ],
            cp,
        );
    }
}

pub(super) fn toilet(p: &mut Parts, rng: &mut R) {
    let (w, d) = (u(rng, 0.38, 0.46), u(rng, 0.55, 0.7));
    let (cb, cp, cl) = (color(rng), color(rng), color(rng));
    let seat_h = u(rng, 0.38, 0.45);
    let tank_d = 0.18;
    let b = p.base(
        &[
            bx(
                v(0.0, -tank_d / 2.0, seat_h / 2.0),
                v(w * 0.8, d - tank_d, seat_h),
            ),
            bx(
                v(0.0, d / 2.0 - tank_d / 2.0, seat_h + 0.2),
                v(w, tank_d, seat_h + 0.4),
            ),
        ],
        cb,
    );
    let y1 = d / 2.0 - tank_d;
    let y0 = -d / 2.0;
    let hinge_y = y1 - 0.01;
    p.part(
        b,
        Revolute,
        v(0.0, hinge_y, seat_h + 0.015),
        v(-1.0, 0.0, 0.0),
        (0.0, u(rng, 1.5, 1.7)),
        &[bx(
            v(0.0, (y0 + hinge_y) / 2.0, seat_h + 0.015),
            v(w, hinge_y - y0, 0.03),
        )],
        cp,
    );
    if rng.random_bool(0.6) {
        p.part(
            b,
            Revolute,
            v(0.0, hinge_y, seat_h + 0.045),
            v(-1.0, 0.0, 0.0),
            (0.0, u(rng, 1.5, 1.7)),
            &[bx(
                v(0.0, (y0 + hinge_y) / 2.0, seat_h + 0.045),
                v(w * 0.95, hinge_y - y0, 0.025),
            )],
            cl,
        );
    }
}

/// The width of a window frame's bars (m).
pub(super) const WINDOW_FRAME: f32 = 0.05;

/// A window's frame, `w` wide and `h` tall from `z0`, `d` deep, with the
/// stand under it, as boxes.
pub(super) fn window_frame(w: f32, h: f32, d: f32, z0: f32) -> Vec<(Vec3, Vec3)> {
    let f = WINDOW_FRAME;
    vec![
        bx(v(-w / 2.0 + f / 2.0, 0.0, z0 + h / 2.0), v(f, d, h)),
        bx(v(w / 2.0 - f / 2.0, 0.0, z0 + h / 2.0), v(f, d, h)),
        bx(v(0.0, 0.0, z0 + f / 2.0), v(w, d, f)),
        bx(v(0.0, 0.0, z0 + h - f / 2.0), v(w, d, f)),
        bx(v(0.0, 0.0, z0 / 2.0), v(w * 0.6, d, z0)),
    ]
}

pub(super) fn window(p: &mut Parts, rng: &mut R) {
    let (w, h, d, z0) = (u(rng, 0.8, 1.1), u(rng, 0.7, 0.95), 0.1, u(rng, 0.1, 0.3));
    let (cb, cp) = (color(rng), color(rng));
    let f = WINDOW_FRAME;
    let mut boxes = window_frame(w, h, d, z0);
    // The fixed pane behind the sliding sash.
    boxes.push(bx(
        v(w / 4.0, 0.02, z0 + h / 2.0),
        v(w / 2.0 - f, 0.02, h - 2.0 * f),
    ));
    let b = p.base(&boxes, cb);
    let (iw, ih) = (w - 2.0 * f, h - 2.0 * f);
    match rng.random_range(0..3) {
        0 => {
            // Horizontal slider: the left sash slides right, in front of the fixed pane.
            let sash = [
                bx(
                    v(-w / 4.0 + f / 2.0, -0.025, z0 + h / 2.0),
                    v(iw / 2.0, 0.02, ih),
                ),
                bx(
                    v(-w / 2.0 + f + 0.04, -0.05, z0 + h / 2.0),
                    v(0.02, 0.03, 0.15),
                ),
            ];
            p.part(
                b,
                Prismatic,
                v(-w / 4.0, -0.025, z0 + h / 2.0),
                v(1.0, 0.0, 0.0),
                (0.0, (iw / 2.0 - 0.02).min(0.45)),
                &sash,
                cp,
            );
        }
        1 => {
            // Vertical slider: the lower sash rises.
            let sash = [
                bx(v(0.0, -0.025, z0 + f + ih / 4.0), v(iw, 0.02, ih / 2.0)),
                bx(v(0.0, -0.05, z0 + f + 0.05), v(0.15, 0.03, 0.02)),
            ];
            p.part(
                b,
                Prismatic,
                v(0.0, -0.025, z0 + f + ih / 4.0),
                v(0.0, 0.0, 1.0),
                (0.0, (ih / 2.0 - 0.02).min(0.45)),
                &sash,
                cp,
            );
        }
        _ => {
            let left = rng.random_bool(0.5);
            Door {
                y_face: -d / 2.0,
                x: (-w / 2.0 + f, w / 2.0 - f),
                z: (z0 + f, z0 + h - f),
                hinge: Hinge::left_if(left),
                upper: u(rng, 1.2, 1.6),
                color: cp,
                thick: 0.03,
            }
            .attach(p, b);
        }
    }
}

pub(super) fn table(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.9, 1.2), u(rng, 0.5, 0.65), u(rng, 0.65, 0.75));
    let (cb, cp) = (color(rng), color(rng));
    let l = 0.05;
    let apron = 0.16;
    let mut boxes = vec![
        bx(v(0.0, 0.0, h - 0.02), v(w, d, 0.04)),
        bx(
            v(0.0, 0.0, h - 0.04 - apron / 2.0),
            v(w - 0.02, d - 0.02, apron),
        ),
    ];
    for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
        boxes.push(bx(
            v(
                sx * (w / 2.0 - l / 2.0),
                sy * (d / 2.0 - l / 2.0),
                (h - 0.04) / 2.0,
            ),
            v(l, l, h - 0.04),
        ));
    }
    let with_door = rng.random_bool(0.35);
    let cab_w = w * 0.35;
    if with_door {
        boxes.push(bx(
            v(w / 2.0 - cab_w / 2.0, 0.0, (h - 0.04 - apron) / 2.0),
            v(cab_w, d - 0.02, h - 0.04 - apron),
        ));
    }
    let b = p.base(&boxes, cb);
    let n = rng.random_range(1..=2);
    let dw = (w - 0.1) / n as f32;
    for k in 0..n {
        let x0 = -w / 2.0 + 0.05 + k as f32 * dw;
        Drawer {
            y_face: -d / 2.0 + 0.01,
            x: (x0 + 0.01, x0 + dw - 0.01),
            z: (h - 0.04 - apron + 0.01, h - 0.05),
            depth: d * 0.8,
            range: u(rng, 0.3, 0.36).min(d * 0.8),
            color: cp,
        }
        .attach(p, b);
    }
    if with_door {
        Door {
            y_face: -d / 2.0 + 0.01,
            x: (w / 2.0 - cab_w + 0.01, w / 2.0 - 0.01),
            z: (0.02, h - 0.05 - apron),
            hinge: Hinge::Right,
            upper: u(rng, 1.4, 1.8),
            color: cp,
            thick: T,
        }
        .attach(p, b);
    }
}

pub(super) fn door(p: &mut Parts, rng: &mut R) {
    // PartNet-Mobility doors at the paper's 0.55 scale: about half a metre wide.
    let (w, h) = (u(rng, 0.45, 0.6), u(rng, 1.05, 1.3));
    let (cb, cp) = (color(rng), color(rng));
    let f = 0.06;
    let b = p.base(
        &[
            bx(v(-w / 2.0 - f / 2.0, 0.0, h / 2.0), v(f, 0.12, h)),
            bx(v(w / 2.0 + f / 2.0, 0.0, h / 2.0), v(f, 0.12, h)),
            bx(v(0.0, 0.0, h + f / 2.0), v(w + 2.0 * f, 0.12, f)),
        ],
        cb,
    );
    Door {
        y_face: -0.03,
        x: (-w / 2.0 + 0.005, w / 2.0 - 0.005),
        z: (0.01, h - 0.005),
        hinge: Hinge::left_if(rng.random_bool(0.5)),
        upper: u(rng, 1.5, 1.9),
        color: cp,
        thick: 0.04,
    }
    .attach(p, b);
}

pub(super) fn folding_chair(p: &mut Parts, rng: &mut R) {
    let (w, d, hs) = (u(rng, 0.4, 0.5), u(rng, 0.4, 0.5), u(rng, 0.42, 0.48));
    let (cb, cp) = (color(rng), color(rng));
    let l = 0.03;
    let b = p.base(
        &[
            bx(v(-w / 2.0, d / 2.0, (hs + 0.45) / 2.0), v(l, l, hs + 0.45)),
            bx(v(w / 2.0, d / 2.0, (hs + 0.45) / 2.0), v(l, l, hs + 0.45)),
            bx(v(-w / 2.0, -d / 2.0, hs / 2.0), v(l, l, hs)),
            bx(v(w / 2.0, -d / 2.0, hs / 2.0), v(l, l, hs)),
            bx(v(0.0, d / 2.0, hs + 0.3), v(w, 0.02, 0.25)),
        ],
        cb,
    );
    p.part(
        b,
        Revolute,
        v(0.0, d / 2.0 - 0.02, hs),
        v(-1.0, 0.0, 0.0),
        (0.0, u(rng, 1.4, 1.57)),
        &[bx(v(0.0, 0.0, hs), v(w - 0.04, d - 0.04, 0.03))],
        cp,
    );
}
