//! Text on pictures: captions and legends drawn with a real font (DejaVu Sans
//! through ab_glyph), antialiased onto RGB images.
use ab_glyph::{Font, FontArc, PxScale, ScaleFont};
use image::{Rgb, RgbImage};
use std::sync::OnceLock;

/// Where DejaVu Sans is found on Debian and other distributions (curve.png uses it too).
pub const FONT_PATHS: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
];

/// The caption font, or None (with one notice) where none is installed:
/// pictures are then written without text rather than not at all.
pub fn font() -> Option<&'static FontArc> {
    static FONT: OnceLock<Option<FontArc>> = OnceLock::new();
    FONT.get_or_init(|| {
        let font = FONT_PATHS
            .iter()
            .find_map(|p| std::fs::read(p).ok())
            .and_then(|bytes| FontArc::try_from_vec(bytes).ok());
        if font.is_none() {
            eprintln!(
                "notice: no DejaVuSans.ttf found (apt-get install fonts-dejavu-core); pictures get no captions"
            );
        }
        font
    })
    .as_ref()
}

/// Width in pixels of `text` at `size` px.
pub fn width(text: &str, size: f32) -> f32 {
    let Some(font) = font() else {
        return 0.0;
    };
    let f = font.as_scaled(PxScale::from(size));
    text.chars().map(|c| f.h_advance(f.glyph_id(c))).sum()
}

/// Draws `text` with its top-left corner at (x, y), `size` px high.
pub fn draw(img: &mut RgbImage, x: f32, y: f32, size: f32, text: &str, color: [u8; 3]) {
    let Some(font) = font() else {
        return;
    };
    let scale = PxScale::from(size);
    let f = font.as_scaled(scale);
    let mut caret = x;
    let baseline = y + f.ascent();
    let mut previous = None;
    for c in text.chars() {
        let id = f.glyph_id(c);
        if let Some(p) = previous {
            caret += f.kern(p, id);
        }
        let glyph = id.with_scale_and_position(scale, ab_glyph::point(caret, baseline));
        caret += f.h_advance(id);
        previous = Some(id);
        let Some(outline) = font.outline_glyph(glyph) else {
            continue;
        };
        let bounds = outline.px_bounds();
        outline.draw(|gx, gy, coverage| {
            let (px, py) = (
                bounds.min.x as i32 + gx as i32,
                bounds.min.y as i32 + gy as i32,
            );
            if px < 0 || py < 0 || px as u32 >= img.width() || py as u32 >= img.height() {
                return;
            }
            let a = coverage.clamp(0.0, 1.0);
            let Rgb(old) = *img.get_pixel(px as u32, py as u32);
            let mut new = [0u8; 3];
            for ((n, o), c) in new.iter_mut().zip(old).zip(color) {
                *n = (o as f32 * (1.0 - a) + c as f32 * a).round() as u8;
            }
            img.put_pixel(px as u32, py as u32, Rgb(new));
        });
    }
}

/// `text` broken into lines at most `max_width` pixels wide at `size`.
pub fn wrap(text: &str, size: f32, max_width: f32) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for word in text.split_whitespace() {
        let candidate = if line.is_empty() {
            word.to_owned()
        } else {
            format!("{line} {word}")
        };
        if !line.is_empty() && width(&candidate, size) > max_width {
            lines.push(std::mem::replace(&mut line, word.to_owned()));
        } else {
            line = candidate;
        }
    }
    if !line.is_empty() {
        lines.push(line);
    }
    lines
}

/// `img` with a white band of `lines` below it, each drawn in dark grey.
pub fn with_caption(img: &RgbImage, lines: &[String]) -> RgbImage {
    let size = (img.width() as f32 / 26.0).clamp(11.0, 20.0);
    let line_h = (size * 1.3).ceil() as u32;
    let band = line_h * lines.len() as u32 + line_h / 3;
    let mut out = RgbImage::from_pixel(img.width(), img.height() + band, Rgb([255, 255, 255]));
    image::imageops::overlay(&mut out, img, 0, 0);
    for (k, line) in lines.iter().enumerate() {
        let y = img.height() as f32 + (line_h / 6) as f32 + (k as u32 * line_h) as f32;
        draw(&mut out, 6.0, y, size, line, [30, 30, 30]);
    }
    out
}
