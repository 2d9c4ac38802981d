//! The parts kit the recipes build from: a body, doors hinged at a side or at
//! the bottom, lids, drawers, each a named set of parameters. Object frame:
//! origin on the floor at the footprint centre, z up, front face toward -y.
#![allow(
    clippy::indexing_slicing,
    reason = "the generator indexes parts it created itself; no input reaches it"
)]
use super::super::builder::Parts;
use crate::math::Vec3;
use crate::model::JointKind::{Prismatic, Revolute};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

pub(super) type R = ChaCha8Rng;

/// A uniform draw in [lo, hi).
pub(super) fn u(rng: &mut R, lo: f32, hi: f32) -> f32 {
    rng.random_range(lo..hi)
}

/// A random colour of moderate saturation and brightness (HSV to RGB).
pub(super) fn color(rng: &mut R) -> [f32; 3] {
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

/// A box as (centre, size).
pub(super) fn bx(centre: Vec3, size: Vec3) -> (Vec3, Vec3) {
    (centre, size)
}

pub(super) fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

/// Panel thickness (m).
pub(super) const T: f32 = 0.025;
/// How far handles stand out (m).
pub(super) const HANDLE: f32 = 0.035;

/// A closed box body of width w, depth d, height h standing at z0.
pub(super) fn body(p: &mut Parts, w: f32, d: f32, h: f32, z0: f32, c: [f32; 3]) -> usize {
    p.base(&[bx(v(0.0, 0.0, z0 + h / 2.0), v(w, d, h))], c)
}

/// The edge a side door turns on, seen from the front.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Hinge {
    Left,
    Right,
}

impl Hinge {
    pub(super) fn left_if(left: bool) -> Self {
        if left { Hinge::Left } else { Hinge::Right }
    }
}

/// A door in front of the face `y = y_face` covering `x` and `z`, hinged on
/// its left or right edge, opening toward -y up to `upper` rad.
pub(super) struct Door {
    pub y_face: f32,
    pub x: (f32, f32),
    pub z: (f32, f32),
    pub hinge: Hinge,
    pub upper: f32,
    pub color: [f32; 3],
    pub thick: f32,
}

impl Door {
    pub(super) fn attach(self, p: &mut Parts, parent: usize) -> usize {
        let Door {
            y_face,
            x: (x0, x1),
            z: (z0, z1),
            hinge,
            upper,
            color,
            thick,
        } = self;
        let yc = y_face - thick / 2.0;
        let (hx, axis, free, handle_side) = match hinge {
            Hinge::Left => (x0, v(0.0, 0.0, -1.0), x1, -0.05),
            Hinge::Right => (x1, v(0.0, 0.0, 1.0), x0, 0.05),
        };
        let handle_x = free + handle_side;
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
            color,
        )
    }
}

/// A door hinged at its bottom edge (oven, dishwasher), opening down toward -y.
pub(super) struct FlapDoor {
    pub y_face: f32,
    pub x: (f32, f32),
    pub z: (f32, f32),
    pub upper: f32,
    pub color: [f32; 3],
}

impl FlapDoor {
    pub(super) fn attach(self, p: &mut Parts, parent: usize) -> usize {
        let FlapDoor {
            y_face,
            x: (x0, x1),
            z: (z0, z1),
            upper,
            color,
        } = self;
        let yc = y_face - T / 2.0;
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
            color,
        )
    }
}

/// A lid on top (`z = top`) spanning `x` and `y`, hinged at the back, lifting
/// its front up to `upper` rad.
pub(super) struct Lid {
    pub top: f32,
    pub x: (f32, f32),
    pub y: (f32, f32),
    pub upper: f32,
    pub color: [f32; 3],
    pub thick: f32,
}

impl Lid {
    pub(super) fn attach(self, p: &mut Parts, parent: usize) -> usize {
        let Lid {
            top,
            x: (x0, x1),
            y: (y0, y1),
            upper,
            color,
            thick,
        } = self;
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
            color,
        )
    }
}

/// A drawer in the face `y = y_face` covering `x` and `z`, `depth` deep,
/// pulled toward -y by up to `range` m.
pub(super) struct Drawer {
    pub y_face: f32,
    pub x: (f32, f32),
    pub z: (f32, f32),
    pub depth: f32,
    pub range: f32,
    pub color: [f32; 3],
}

impl Drawer {
    pub(super) fn attach(self, p: &mut Parts, parent: usize) -> usize {
        let Drawer {
            y_face,
            x: (x0, x1),
            z: (z0, z1),
            depth,
            range,
            color,
        } = self;
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
            color,
        )
    }
}
