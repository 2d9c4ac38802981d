//! PNG pictures of frames: colour, depth with a legend, segmentation, normals,
//! and per-step overlays (grasp point, executed and candidate directions).
use anyhow::{Context, Result};
use image::{Rgb, RgbImage};
use std::path::Path;
use umpnet_sim::math::Vec3;
use umpnet_sim::render::{Frame, SEG_BACKGROUND};

pub fn color_image(f: &Frame) -> RgbImage {
    RgbImage::from_raw(f.width, f.height, f.rgb.clone())
        .unwrap_or_else(|| RgbImage::new(f.width, f.height))
}

/// Turbo-like colour map on [0, 1].
fn colormap(t: f32) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0);
    let stops = [
        [48.0, 18.0, 59.0],
        [40.0, 150.0, 230.0],
        [90.0, 230.0, 110.0],
        [245.0, 200.0, 40.0],
        [190.0, 30.0, 10.0],
    ];
    let x = t * (stops.len() - 1) as f32;
    let i = (x as usize).min(stops.len() - 2);
    let a = x - i as f32;
    match (stops.get(i), stops.get(i + 1)) {
        (Some(s0), Some(s1)) => {
            let mut out = [0u8; 3];
            for ((o, x0), x1) in out.iter_mut().zip(s0).zip(s1) {
                *o = (x0 * (1.0 - a) + x1 * a) as u8;
            }
            out
        }
        _ => [0, 0, 0],
    }
}

pub fn depth_image(f: &Frame) -> (RgbImage, f32, f32) {
    let valid: Vec<f32> = f.depth.iter().copied().filter(|d| *d > 0.0).collect();
    let lo = valid.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = valid.iter().copied().fold(0.0f32, f32::max);
    // The legend bar, then room for its numbers (metres) beside it.
    let bar_w = 40.max(f.width / 10);
    let legend_w = bar_w + 56;
    let mut img = RgbImage::from_pixel(f.width + legend_w, f.height, Rgb([255, 255, 255]));
    for r in 0..f.height {
        for c in 0..f.width {
            let d = f.depth.get(f.index(r, c)).copied().unwrap_or(0.0);
            let px = if d > 0.0 {
                colormap((d - lo) / (hi - lo).max(1e-6))
            } else {
                [0, 0, 0]
            };
            img.put_pixel(c, r, Rgb(px));
        }
        // Legend: near at the top, far at the bottom, with tick marks every 0.25 m.
        let t = r as f32 / (f.height - 1).max(1) as f32;
        let d = lo + t * (hi - lo);
        let tick = ((d / 0.25).round() * 0.25 - d).abs() < (hi - lo) / f.height as f32;
        for c in f.width + 4..f.width + bar_w {
            let px = if tick && c > f.width + bar_w / 2 {
                [255, 255, 255]
            } else {
                colormap(t)
            };
            img.put_pixel(c, r, Rgb(px));
        }
    }
    if valid.is_empty() {
        return (img, lo, hi);
    }
    // Near at the top, far at the bottom, and the middle.
    let size = (f.height as f32 / 20.0).clamp(10.0, 16.0);
    let x = (f.width + bar_w + 4) as f32;
    let bottom = f.height as f32 - size - 2.0;
    for (y, d) in [(1.0, lo), (bottom / 2.0, 0.5 * (lo + hi)), (bottom, hi)] {
        crate::text::draw(&mut img, x, y, size, &format!("{d:.2} m"), [30, 30, 30]);
    }
    (img, lo, hi)
}

pub fn segmentation_image(f: &Frame) -> RgbImage {
    let mut img = RgbImage::new(f.width, f.height);
    for (i, &s) in f.segmentation.iter().enumerate() {
        let px = if s == SEG_BACKGROUND {
            [0, 0, 0]
        } else {
            let h = s.wrapping_mul(2_654_435_761) >> 8;
            [
                (h & 0xFF) as u8 | 0x30,
                ((h >> 8) & 0xFF) as u8 | 0x30,
                ((h >> 16) & 0xFF) as u8 | 0x30,
            ]
        };
        img.put_pixel(i as u32 % f.width, i as u32 / f.width, Rgb(px));
    }
    img
}

pub fn normal_image(f: &Frame) -> RgbImage {
    let mut img = RgbImage::new(f.width, f.height);
    for (i, (n, d)) in f.normal_in_world.iter().zip(&f.depth).enumerate() {
        let px = if *d > 0.0 {
            n.map(|v| ((v * 0.5 + 0.5) * 255.0) as u8)
        } else {
            [0, 0, 0]
        };
        img.put_pixel(i as u32 % f.width, i as u32 / f.width, Rgb(px));
    }
    img
}

/// Encodes in memory, then writes atomically (see `umpnet_sim::fsio`).
pub fn save(img: &RgbImage, path: &Path) -> Result<()> {
    let mut png = std::io::Cursor::new(Vec::new());
    img.write_to(&mut png, image::ImageFormat::Png)
        .with_context(|| format!("encoding {}", path.display()))?;
    Ok(umpnet_sim::fsio::write_atomic(path, png.get_ref())?)
}

/// Projects a world point into pixel coordinates (x = col, y = row).
pub fn project(f: &Frame, p: Vec3) -> Option<(f32, f32)> {
    let c = f.world_from_camera.inverse_transform_point(p);
    (c.z > 1e-3).then(|| {
        (
            f.intrinsics.fx * c.x / c.z + f.intrinsics.cx,
            f.intrinsics.fy * c.y / c.z + f.intrinsics.cy,
        )
    })
}

pub fn draw_line(img: &mut RgbImage, a: (f32, f32), b: (f32, f32), color: [u8; 3], thick: i32) {
    let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()) as usize).max(1);
    for k in 0..=n {
        let t = k as f32 / n as f32;
        let (x, y) = (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
        for dx in -thick / 2..=thick / 2 {
            for dy in -thick / 2..=thick / 2 {
                let (px, py) = (x as i32 + dx, y as i32 + dy);
                if px >= 0 && py >= 0 && (px as u32) < img.width() && (py as u32) < img.height() {
                    img.put_pixel(px as u32, py as u32, Rgb(color));
                }
            }
        }
    }
}

pub fn draw_disc(img: &mut RgbImage, c: (f32, f32), r: f32, color: [u8; 3]) {
    let ri = r.ceil() as i32;
    for dx in -ri..=ri {
        for dy in -ri..=ri {
            if (dx * dx + dy * dy) as f32 <= r * r {
                let (px, py) = (c.0 as i32 + dx, c.1 as i32 + dy);
                if px >= 0 && py >= 0 && (px as u32) < img.width() && (py as u32) < img.height() {
                    img.put_pixel(px as u32, py as u32, Rgb(color));
                }
            }
        }
    }
}

/// Draws an arrow from a world point along a world direction of `length` metres.
pub fn draw_arrow(
    img: &mut RgbImage,
    f: &Frame,
    from: Vec3,
    dir: Vec3,
    length: f32,
    color: [u8; 3],
    thick: i32,
) {
    let (Some(a), Some(b)) = (project(f, from), project(f, from + dir * length)) else {
        return;
    };
    draw_line(img, a, b, color, thick);
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let l = (dx * dx + dy * dy).sqrt().max(1e-3);
    let (ux, uy) = (dx / l, dy / l);
    let s = (l * 0.3).min(8.0 * thick as f32);
    for sgn in [-1.0f32, 1.0] {
        let tip = (
            b.0 - s * (ux - sgn * 0.5 * uy),
            b.1 - s * (uy + sgn * 0.5 * ux),
        );
        draw_line(img, b, tip, color, thick);
    }
}
