//! Pictures of one episode for people: each step drawn at a display size
//! (whatever the policy sees, which is shown as an inset), with the grasp
//! where the part has taken it, captions in words, a title that says what
//! ran and how it ended, a contact sheet and an animated GIF.
use crate::{images, text};
use anyhow::Result;
use image::{RgbImage, imageops};
use umpnet_eval::episode::{HookFrame, Step};
use umpnet_sim::camera::Camera;
use umpnet_sim::env::SimEnv;
use umpnet_sim::math::Vec3;
use umpnet_sim::render::{Frame, RendererKind, create_renderer};
use umpnet_sim::scene::Scene;

/// Candidate arrows drawn per step: the most promising ones, not a blur of all.
const SHOWN_CANDIDATES: usize = 8;
pub const GRASP: [u8; 3] = [255, 40, 40];
pub const EXECUTED: [u8; 3] = [255, 220, 0];
pub const FORWARD: [u8; 3] = [40, 200, 60];
pub const BACKWARD: [u8; 3] = [230, 60, 200];
pub const NO_MOVE: [u8; 3] = [160, 160, 160];

fn aot_color(aot: Option<&i8>) -> [u8; 3] {
    match aot {
        Some(1) => FORWARD,
        Some(-1) => BACKWARD,
        _ => NO_MOVE,
    }
}

/// An Arrow-of-Time label in words, against the state it is judged from.
fn aot_words(aot: i8, reference: &str) -> String {
    match aot {
        1 => format!("away from {reference}"),
        -1 => format!("back toward {reference}"),
        _ => "neither away nor back".to_owned(),
    }
}

/// The scene again, on its own renderer and a camera of the display size:
/// each step's parts, posed by the episode's environment, drawn large.
pub struct Display {
    env: SimEnv,
}

impl Display {
    pub fn new(scene: &Scene, size: (u32, u32), renderer: RendererKind) -> Result<Self> {
        let camera = Camera::reference(size.0, size.1);
        Ok(Self {
            env: SimEnv::new(scene.clone(), camera, create_renderer(renderer)?)?,
        })
    }

    /// One step's tile (untitled): the display frame with its marks, the
    /// policy's view as an inset, and the captions below.
    pub fn step(&mut self, h: &HookFrame<'_>) -> Result<Tile> {
        let f = self.env.render_parts(&h.env.part_transforms())?;
        let mut img = images::color_image(&f);
        let scale = f.width as f32 / 320.0;
        let thick = (2.0 * scale).round().max(1.0) as i32;
        let mut captions = Vec::with_capacity(3);
        let mut grasp = h
            .env
            .grasp_point_in_world()
            .and_then(|p| images::project(&f, p));
        if grasp.is_none() && h.t == 0 {
            // Nothing grasped: the chosen pixel, carried to the display size.
            let (sy, sx) = (
                f.height as f32 / h.frame.height as f32,
                f.width as f32 / h.frame.width as f32,
            );
            grasp = Some(((h.pixel.1 as f32 + 0.5) * sx, (h.pixel.0 as f32 + 0.5) * sy));
        }
        match h.step {
            None => {
                let what = if h.env.grasped_joint().is_some() {
                    "start: grasped at"
                } else {
                    "start: nothing movable at"
                };
                captions.push(format!(
                    "{what} row {}, column {} of the policy's view",
                    h.pixel.0, h.pixel.1
                ));
                captions.extend([String::new(), String::new()]);
            }
            Some(s) => self.marks(&mut img, &f, s, thick, h.t, &mut captions),
        }
        if let Some(g) = grasp {
            images::draw_disc(&mut img, g, 4.0 * scale.max(0.5), GRASP);
        }
        inset(&mut img, &images::color_image(h.frame));
        Ok(Tile { img, captions })
    }

    fn marks(
        &self,
        img: &mut RgbImage,
        f: &Frame,
        s: &Step,
        thick: i32,
        t: usize,
        captions: &mut Vec<String>,
    ) {
        let l = &s.record.labels;
        captions.push(format!(
            "step {t}: joint {:.2} -> {:.2}",
            l.joint_before, l.joint_after
        ));
        // Arrows start where the gripper was when the action began.
        let from = Vec3::from(s.gripper_in_world);
        let mut predicted = None;
        if let Some(c) = &s.candidates {
            let maxd = c.distance.iter().copied().fold(1e-6f32, f32::max);
            let mut order: Vec<usize> = (0..c.directions.len()).collect();
            let d = |k: usize| c.distance.get(k).copied().unwrap_or(0.0);
            order.sort_by(|&a, &b| d(b).total_cmp(&d(a)));
            for &k in order.iter().take(SHOWN_CANDIDATES) {
                let Some(dir) = c.directions.get(k) else {
                    continue;
                };
                let length = 0.2 * d(k).max(0.0) / maxd;
                images::draw_arrow(
                    img,
                    f,
                    from,
                    Vec3::from(*dir),
                    length,
                    aot_color(c.aot.get(k)),
                    thick.max(1),
                );
            }
            // The executed direction's own prediction, if it is a candidate.
            predicted = c
                .index_of(Vec3::from(s.record.direction))
                .and_then(|k| Some((*c.distance.get(k)?, *c.aot.get(k)?)));
        }
        images::draw_arrow(
            img,
            f,
            from,
            Vec3::from(s.record.direction),
            0.25,
            EXECUTED,
            thick + 1,
        );
        // The network's AoT is relative to its reference image (the goal, in
        // the goal task); the simulator's to the episode's start.
        let reference = if self.env.scene().goal.is_some() {
            "the goal"
        } else {
            "the start"
        };
        captions.push(match predicted {
            Some((d, aot)) => format!(
                "network: would move it {d:.2}, {}",
                aot_words(aot, reference)
            ),
            None => "network: no prediction for this move".to_owned(),
        });
        captions.push(format!(
            "simulator: moved it {:.2}, {}",
            l.r_dist,
            aot_words(l.aot, "the start")
        ));
    }

    /// The goal state as a tile, captioned like the steps.
    pub fn goal(&mut self) -> Result<Option<Tile>> {
        let Some(value) = self
            .env
            .scene()
            .goal
            .as_ref()
            .map(|g| g.joints.get(g.joint).copied())
        else {
            return Ok(None);
        };
        let Some(f) = self.env.render_goal()? else {
            return Ok(None);
        };
        let line = value.map_or(String::new(), |v| format!("the joint at the goal: {v:.2}"));
        Ok(Some(Tile {
            img: images::color_image(&f),
            captions: vec!["goal".to_owned(), line, String::new()],
        }))
    }
}

/// The policy's own view, small, in the top right corner with a white frame.
fn inset(img: &mut RgbImage, view: &RgbImage) {
    let w = (img.width() / 4).max(view.width().min(img.width()));
    let h = (w as f32 * view.height() as f32 / view.width() as f32).round() as u32;
    if w + 8 > img.width() || h + 8 > img.height() {
        return;
    }
    let small = imageops::resize(view, w, h, imageops::FilterType::Nearest);
    let (x, y) = (img.width() - w - 6, 6);
    for dx in 0..w + 4 {
        for dy in 0..h + 4 {
            img.put_pixel(x + dx - 2, y + dy - 2, image::Rgb([255, 255, 255]));
        }
    }
    imageops::overlay(img, &small, i64::from(x), i64::from(y));
}

/// A drawn frame and the lines that explain it.
#[derive(Clone)]
pub struct Tile {
    pub img: RgbImage,
    pub captions: Vec<String>,
}

impl Tile {
    /// The tile at `width` pixels across, captions drawn at that size.
    pub fn at_width(&self, width: u32) -> RgbImage {
        let img = if width == self.img.width() {
            self.img.clone()
        } else {
            let h =
                (self.img.height() as f32 * width as f32 / self.img.width() as f32).round() as u32;
            imageops::resize(&self.img, width, h.max(1), imageops::FilterType::Triangle)
        };
        text::with_caption(&img, &self.captions)
    }
}

/// `img` under a band with `title`, drawn to fit its width.
pub fn with_title(img: &RgbImage, title: &str) -> RgbImage {
    let mut size = (img.width() as f32 / 32.0).clamp(12.0, 22.0);
    while size > 9.0 && text::width(title, size) > img.width() as f32 - 12.0 {
        size -= 1.0;
    }
    let band = (size * 1.8).ceil() as u32;
    let mut out = RgbImage::from_pixel(img.width(), img.height() + band, image::Rgb([40, 44, 52]));
    imageops::overlay(&mut out, img, 0, i64::from(band));
    text::draw(
        &mut out,
        6.0,
        (band as f32 - size) / 2.0 - 1.0,
        size,
        title,
        [245, 245, 245],
    );
    out
}

/// The tiles in a grid under the title, then a legend of the marks that
/// explains forward and backward once.
pub fn contact_sheet(tiles: &[Tile], title: &str) -> RgbImage {
    let Some(first) = tiles.first() else {
        return RgbImage::new(1, 1);
    };
    // Many steps: half-size tiles keep the sheet a picture, not a poster.
    let width = if tiles.len() > 4 {
        (first.img.width() / 2).max(320)
    } else {
        first.img.width()
    };
    let drawn: Vec<RgbImage> = tiles.iter().map(|t| t.at_width(width)).collect();
    let cols = (drawn.len() as f32).sqrt().ceil() as u32;
    let rows = (drawn.len() as u32).div_ceil(cols);
    let h = drawn.iter().map(RgbImage::height).max().unwrap_or(1);
    let sheet_w = (cols * width).max(720);
    let explained = text::wrap(AOT_LEGEND, 13.0, sheet_w as f32 - 16.0);
    let legend_h = 30 + 17 * explained.len() as u32;
    let mut sheet = RgbImage::from_pixel(sheet_w, rows * h + legend_h, image::Rgb([255, 255, 255]));
    for (i, p) in drawn.iter().enumerate() {
        imageops::overlay(
            &mut sheet,
            p,
            i64::from((i as u32 % cols) * width),
            i64::from((i as u32 / cols) * h),
        );
    }
    let y = (rows * h) as f32 + 14.0;
    let mut x = 8.0;
    for (color, label, arrow) in [
        (GRASP, "grasp", false),
        (EXECUTED, "move made", true),
        (FORWARD, "candidate: forward", true),
        (BACKWARD, "backward", true),
        (NO_MOVE, "no change", true),
    ] {
        if arrow {
            images::draw_line(&mut sheet, (x, y), (x + 18.0, y), color, 3);
        } else {
            images::draw_disc(&mut sheet, (x + 8.0, y), 5.0, color);
        }
        x += 24.0;
        text::draw(&mut sheet, x, y - 8.0, 14.0, label, [30, 30, 30]);
        x += text::width(label, 14.0) + 16.0;
    }
    for (k, line) in explained.iter().enumerate() {
        text::draw(
            &mut sheet,
            8.0,
            y + 12.0 + 17.0 * k as f32,
            13.0,
            line,
            [70, 70, 70],
        );
    }
    with_title(&sheet, title)
}

const AOT_LEGEND: &str = "forward / backward (the Arrow of Time): whether a move takes the object \
further from a reference state or back toward it. The network's reference is the start when \
exploring and the goal when seeking one; the simulator's is always the start.";

pub fn write_gif(frames: &[RgbImage], path: &std::path::Path) -> Result<()> {
    let mut bytes = Vec::new();
    let mut enc = image::codecs::gif::GifEncoder::new_with_speed(&mut bytes, 10);
    enc.set_repeat(image::codecs::gif::Repeat::Infinite)?;
    for p in frames {
        let rgba = image::DynamicImage::ImageRgb8(p.clone()).to_rgba8();
        enc.encode_frame(image::Frame::from_parts(
            rgba,
            0,
            0,
            image::Delay::from_numer_denom_ms(600, 1),
        ))?;
    }
    drop(enc);
    Ok(umpnet_sim::fsio::write_atomic(path, &bytes)?)
}
