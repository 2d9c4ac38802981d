//! Parametric families for the paper's 22 categories. Object frame: origin on
//! the floor at the footprint centre, z up, front face toward -y (the camera).
#![allow(
    clippy::indexing_slicing,
    reason = "the generator indexes parts it created itself; no input reaches it"
)]
use super::Category;
use super::builder::Parts;
use crate::math::Vec3;
use crate::model::JointKind::{Prismatic, Revolute};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

type R = ChaCha8Rng;

fn u(rng: &mut R, lo: f32, hi: f32) -> f32 {
    rng.random_range(lo..hi)
}

fn color(rng: &mut R) -> [f32; 3] {
    let h = u(rng, 0.0, 6.0);
    let (s, v) = (u(rng, 0.25, 0.7), u(rng, 0.55, 0.95));
    let c = v * s;
    let x = c * (1.0 - ((h % 2.0) - 1.0).abs());
    let (r, g, b) = match h as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    [r + m, g + m, b + m]
}

fn bx(centre: Vec3, size: Vec3) -> (Vec3, Vec3) {
    (centre, size)
}
fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

const T: f32 = 0.025; // panel thickness
const HANDLE: f32 = 0.035; // how far handles stand out

/// A closed box body of width w, depth d, height h standing on the floor.
fn body(p: &mut Parts, w: f32, d: f32, h: f32, z0: f32, c: [f32; 3]) -> usize {
    p.base(&[bx(v(0.0, 0.0, z0 + h / 2.0), v(w, d, h))], c)
}

/// Door in front of the face y = y_face covering x0..x1, z0..z1, hinged on the
/// left (x0) or right (x1) edge, opening toward -y.
#[allow(clippy::too_many_arguments)]
fn side_door(
    p: &mut Parts,
    parent: usize,
    y_face: f32,
    x: (f32, f32),
    z: (f32, f32),
    hinge_left: bool,
    upper: f32,
    c: [f32; 3],
    thick: f32,
) -> usize {
    let (x0, x1) = x;
    let (z0, z1) = z;
    let yc = y_face - thick / 2.0;
    let (hx, axis, free) = if hinge_left {
        (x0, v(0.0, 0.0, -1.0), x1)
    } else {
        (x1, v(0.0, 0.0, 1.0), x0)
    };
    let handle_x = free + if hinge_left { -0.05 } else { 0.05 };
    let zm = (z0 + z1) / 2.0;
    p.part(
        parent,
        Revolute,
        v(hx, yc, zm),
        axis,
        (0.0, upper),
        &[
            bx(v((x0 + x1) / 2.0, yc, zm), v(x1 - x0, thick, z1 - z0)),
            bx(
                v(handle_x, y_face - thick - HANDLE / 2.0, zm),
                v(0.025, HANDLE, (z1 - z0).min(0.3) * 0.5),
            ),
        ],
        c,
    )
}

/// Door hinged at its bottom edge (oven, dishwasher), opening down toward -y.
fn flap_door(
    p: &mut Parts,
    parent: usize,
    y_face: f32,
    x: (f32, f32),
    z: (f32, f32),
    upper: f32,
    c: [f32; 3],
) -> usize {
    let yc = y_face - T / 2.0;
    let (x0, x1) = x;
    let (z0, z1) = z;
    p.part(
        parent,
        Revolute,
        v((x0 + x1) / 2.0, yc, z0),
        v(1.0, 0.0, 0.0),
        (0.0, upper),
        &[
            bx(
                v((x0 + x1) / 2.0, yc, (z0 + z1) / 2.0),
                v(x1 - x0, T, z1 - z0),
            ),
            bx(
                v((x0 + x1) / 2.0, y_face - T - HANDLE / 2.0, z1 - 0.05),
                v((x1 - x0) * 0.6, HANDLE, 0.025),
            ),
        ],
        c,
    )
}

/// Lid on top (z = top) spanning x0..x1, y0..y1, hinged at the back (y1), lifting its front.
#[allow(clippy::too_many_arguments)]
fn lid(
    p: &mut Parts,
    parent: usize,
    top: f32,
    x: (f32, f32),
    y: (f32, f32),
    upper: f32,
    c: [f32; 3],
    thick: f32,
) -> usize {
    let (x0, x1) = x;
    let (y0, y1) = y;
    let zc = top + thick / 2.0;
    p.part(
        parent,
        Revolute,
        v((x0 + x1) / 2.0, y1, zc),
        v(-1.0, 0.0, 0.0),
        (0.0, upper),
        &[
            bx(
                v((x0 + x1) / 2.0, (y0 + y1) / 2.0, zc),
                v(x1 - x0, y1 - y0, thick),
            ),
            bx(
                v((x0 + x1) / 2.0, y0 - 0.015, zc),
                v((x1 - x0) * 0.4, 0.03, thick * 1.2),
            ),
        ],
        c,
    )
}

/// Drawer in the face y = y_face covering x0..x1, z0..z1, pulled toward -y.
#[allow(clippy::too_many_arguments)]
fn drawer(
    p: &mut Parts,
    parent: usize,
    y_face: f32,
    x: (f32, f32),
    z: (f32, f32),
    depth: f32,
    range: f32,
    c: [f32; 3],
) -> usize {
    let (x0, x1) = x;
    let (z0, z1) = z;
    let (xc, zc, w, h) = ((x0 + x1) / 2.0, (z0 + z1) / 2.0, x1 - x0, z1 - z0);
    let front = y_face - T / 2.0;
    let tray_h = h * 0.7;
    let tray_z = z0 + 0.02 + tray_h / 2.0;
    p.part(
        parent,
        Prismatic,
        v(xc, front, zc),
        v(0.0, -1.0, 0.0),
        (0.0, range),
        &[
            bx(v(xc, front, zc), v(w, T, h)),
            bx(
                v(xc, y_face + depth / 2.0, z0 + 0.02),
                v(w * 0.9, depth, 0.01),
            ),
            bx(
                v(x0 + 0.03, y_face + depth / 2.0, tray_z),
                v(0.01, depth, tray_h),
            ),
            bx(
                v(x1 - 0.03, y_face + depth / 2.0, tray_z),
                v(0.01, depth, tray_h),
            ),
            bx(
                v(xc, y_face - T - HANDLE / 2.0, zc),
                v(w * 0.4, HANDLE, 0.025),
            ),
        ],
        c,
    )
}

fn cabinet(p: &mut Parts, rng: &mut R) {
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
        drawer(
            p,
            b,
            y,
            (-w / 2.0 + 0.03, w / 2.0 - 0.03),
            (top - drawer_h + 0.01, top - 0.01),
            d * 0.85,
            u(rng, 0.3, 0.36).min(d * 0.85),
            cp,
        );
        top -= drawer_h;
    }
    if layout != 1 {
        let two = w > 0.6 && rng.random_bool(0.6);
        let (x0, x1) = (-w / 2.0 + 0.02, w / 2.0 - 0.02);
        let z = (0.05, top - 0.01);
        let upper = u(rng, 1.5, 2.0);
        if two {
            side_door(p, b, y, (x0, -0.005), z, true, upper, cp, T);
            side_door(p, b, y, (0.005, x1), z, false, upper, cp, T);
        } else {
            side_door(p, b, y, (x0, x1), z, rng.random_bool(0.5), upper, cp, T);
        }
    }
}

fn refrigerator(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.5, 0.7), u(rng, 0.45, 0.6), u(rng, 0.95, 1.25));
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, w, d, h, 0.0, cb);
    let (x0, x1, y) = (-w / 2.0 + 0.01, w / 2.0 - 0.01, -d / 2.0);
    let upper = u(rng, 1.4, 2.0);
    match rng.random_range(0..3) {
        0 => {
            side_door(
                p,
                b,
                y,
                (x0, x1),
                (0.04, h - 0.02),
                rng.random_bool(0.5),
                upper,
                cp,
                0.04,
            );
        }
        1 => {
            let split = h * u(rng, 0.6, 0.7);
            let left = rng.random_bool(0.5);
            side_door(
                p,
                b,
                y,
                (x0, x1),
                (0.04, split - 0.01),
                left,
                upper,
                cp,
                0.04,
            );
            side_door(
                p,
                b,
                y,
                (x0, x1),
                (split + 0.01, h - 0.02),
                left,
                upper,
                cp,
                0.04,
            );
        }
        _ => {
            side_door(
                p,
                b,
                y,
                (x0, -0.005),
                (0.04, h - 0.02),
                true,
                upper,
                cp,
                0.04,
            );
            side_door(
                p,
                b,
                y,
                (0.005, x1),
                (0.04, h - 0.02),
                false,
                upper,
                cp,
                0.04,
            );
        }
    }
}

fn microwave(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.55, 0.75), u(rng, 0.35, 0.45), u(rng, 0.32, 0.45));
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, w, d, h, 0.0, cb);
    let door_w = w * u(rng, 0.68, 0.78);
    side_door(
        p,
        b,
        -d / 2.0,
        (-w / 2.0 + 0.01, -w / 2.0 + door_w),
        (0.02, h - 0.02),
        true,
        u(rng, 1.4, 1.9),
        cp,
        T,
    );
}

fn safe(p: &mut Parts, rng: &mut R) {
    let s = u(rng, 0.4, 0.6);
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, s * u(rng, 0.9, 1.1), s, s * u(rng, 0.9, 1.3), 0.0, cb);
    let (w, h) = p.links[b]
        .mesh
        .bounds()
        .map(|(lo, hi)| (hi.x - lo.x, hi.z - lo.z))
        .unwrap_or((s, s));
    side_door(
        p,
        b,
        -s / 2.0,
        (-w / 2.0 + 0.03, w / 2.0 - 0.03),
        (0.03, h - 0.03),
        rng.random_bool(0.5),
        u(rng, 1.5, 1.9),
        cp,
        0.05,
    );
}

fn washing_machine(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.55, 0.65), u(rng, 0.5, 0.6), u(rng, 0.8, 0.9));
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, w, d, h, 0.0, cb);
    let door = w * u(rng, 0.6, 0.75);
    let zc = h * u(rng, 0.45, 0.55);
    side_door(
        p,
        b,
        -d / 2.0,
        (-door / 2.0, door / 2.0),
        (zc - door / 2.0, zc + door / 2.0),
        rng.random_bool(0.7),
        u(rng, 1.5, 1.9),
        cp,
        0.04,
    );
}

fn oven(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.55, 0.7), u(rng, 0.5, 0.6), u(rng, 0.75, 0.9));
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, w, d, h, 0.0, cb);
    flap_door(
        p,
        b,
        -d / 2.0,
        (-w / 2.0 + 0.03, w / 2.0 - 0.03),
        (0.08, h * u(rng, 0.7, 0.8)),
        u(rng, 1.35, 1.57),
        cp,
    );
}

fn dishwasher(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.55, 0.65), u(rng, 0.5, 0.6), u(rng, 0.8, 0.9));
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, w, d, h, 0.0, cb);
    flap_door(
        p,
        b,
        -d / 2.0,
        (-w / 2.0 + 0.01, w / 2.0 - 0.01),
        (0.06, h - 0.02),
        u(rng, 1.4, 1.57),
        cp,
    );
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

fn box_lid_family(p: &mut Parts, rng: &mut R, dims: (f32, f32, f32), upper: (f32, f32)) {
    let (w, d, h) = dims;
    let (cb, cp) = (color(rng), color(rng));
    let b = body(p, w, d, h, 0.0, cb);
    lid(
        p,
        b,
        h,
        (-w / 2.0, w / 2.0),
        (-d / 2.0, d / 2.0),
        u(rng, upper.0, upper.1),
        cp,
        0.03,
    );
}

fn laptop(p: &mut Parts, rng: &mut R) {
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

fn phone(p: &mut Parts, rng: &mut R) {
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

fn stapler(p: &mut Parts, rng: &mut R) {
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

fn trash_can(p: &mut Parts, rng: &mut R) {
    let (w, d, h) = (u(rng, 0.38, 0.5), u(rng, 0.38, 0.5), u(rng, 0.55, 0.8));
    let (cb, cp) = (color(rng), color(rng));
    if rng.random_bool(0.5) {
        let b = body(p, w, d, h, 0.0, cb);
        lid(
            p,
            b,
            h,
            (-w / 2.0, w / 2.0),
            (-d / 2.0, d / 2.0),
            u(rng, 1.3, 1.8),
            cp,
            0.03,
        );
    } else {
        // Pull-out bin in a cabinet.
        let b = body(p, w, d, h, 0.0, cb);
        drawer(
            p,
            b,
            -d / 2.0,
            (-w / 2.0 + 0.02, w / 2.0 - 0.02),
            (0.04, h - 0.04),
            d * 0.85,
            u(rng, 0.3, 0.36).min(d * 0.85),
            cp,
        );
    }
}

fn toilet(p: &mut Parts, rng: &mut R) {
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

fn window(p: &mut Parts, rng: &mut R) {
    let (w, h, d, z0) = (u(rng, 0.8, 1.1), u(rng, 0.7, 0.95), 0.1, u(rng, 0.1, 0.3));
    let (cb, cp) = (color(rng), color(rng));
    let f = 0.05;
    let b = p.base(
        &[
            bx(v(-w / 2.0 + f / 2.0, 0.0, z0 + h / 2.0), v(f, d, h)),
            bx(v(w / 2.0 - f / 2.0, 0.0, z0 + h / 2.0), v(f, d, h)),
            bx(v(0.0, 0.0, z0 + f / 2.0), v(w, d, f)),
            bx(v(0.0, 0.0, z0 + h - f / 2.0), v(w, d, f)),
            bx(v(0.0, 0.0, z0 / 2.0), v(w * 0.6, d, z0)),
            bx(
                v(w / 4.0, 0.02, z0 + h / 2.0),
                v(w / 2.0 - f, 0.02, h - 2.0 * f),
            ),
        ],
        cb,
    );
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
            side_door(
                p,
                b,
                -d / 2.0,
                (-w / 2.0 + f, w / 2.0 - f),
                (z0 + f, z0 + h - f),
                left,
                u(rng, 1.2, 1.6),
                cp,
                0.03,
            );
        }
    }
}

fn switch(p: &mut Parts, rng: &mut R) {
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

fn folding_chair(p: &mut Parts, rng: &mut R) {
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

fn kettle(p: &mut Parts, rng: &mut R) {
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
        lid(
            p,
            b,
            h,
            (-lw / 2.0, lw / 2.0),
            (-lw / 2.0, lw / 2.0),
            u(rng, 1.3, 1.8),
            cp,
            0.03,
        );
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

fn kitchen_pot(p: &mut Parts, rng: &mut R) {
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

fn bucket(p: &mut Parts, rng: &mut R) {
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

fn table(p: &mut Parts, rng: &mut R) {
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
        drawer(
            p,
            b,
            -d / 2.0 + 0.01,
            (x0 + 0.01, x0 + dw - 0.01),
            (h - 0.04 - apron + 0.01, h - 0.05),
            d * 0.8,
            u(rng, 0.3, 0.36).min(d * 0.8),
            cp,
        );
    }
    if with_door {
        side_door(
            p,
            b,
            -d / 2.0 + 0.01,
            (w / 2.0 - cab_w + 0.01, w / 2.0 - 0.01),
            (0.02, h - 0.05 - apron),
            false,
            u(rng, 1.4, 1.8),
            cp,
            T,
        );
    }
}

fn door(p: &mut Parts, rng: &mut R) {
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
    side_door(
        p,
        b,
        -0.03,
        (-w / 2.0 + 0.005, w / 2.0 - 0.005),
        (0.01, h - 0.005),
        rng.random_bool(0.5),
        u(rng, 1.5, 1.9),
        cp,
        0.04,
    );
}

/// The Toy: a knob travelling along a curved track in a panel. Training
/// instances curve one way (track centre below the knob), test instances the
/// other (centre above), so the direction must turn at every step.
fn toy(p: &mut Parts, rng: &mut R, test: bool) {
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

pub(crate) fn build(category: Category, rng: &mut R, test_instance: bool) -> Parts {
    let mut p = Parts::default();
    match category {
        Category::Refrigerator => refrigerator(&mut p, rng),
        Category::FoldingChair => folding_chair(&mut p, rng),
        Category::Laptop => laptop(&mut p, rng),
        Category::Stapler => stapler(&mut p, rng),
        Category::TrashCan => trash_can(&mut p, rng),
        Category::Microwave => microwave(&mut p, rng),
        Category::Toilet => toilet(&mut p, rng),
        Category::Window => window(&mut p, rng),
        Category::StorageFurniture => cabinet(&mut p, rng),
        Category::Switch => switch(&mut p, rng),
        Category::Kettle => kettle(&mut p, rng),
        Category::Toy => toy(&mut p, rng, test_instance),
        Category::Box => {
            let dims = (u(rng, 0.4, 0.65), u(rng, 0.35, 0.5), u(rng, 0.25, 0.45));
            box_lid_family(&mut p, rng, dims, (1.6, 2.2))
        }
        Category::Phone => phone(&mut p, rng),
        Category::Dishwasher => dishwasher(&mut p, rng),
        Category::Safe => safe(&mut p, rng),
        Category::Oven => oven(&mut p, rng),
        Category::WashingMachine => washing_machine(&mut p, rng),
        Category::Table => table(&mut p, rng),
        Category::KitchenPot => kitchen_pot(&mut p, rng),
        Category::Bucket => bucket(&mut p, rng),
        Category::Door => door(&mut p, rng),
    }
    p
}
