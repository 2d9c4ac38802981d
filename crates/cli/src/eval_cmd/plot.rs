//! curve.png and curve.svg: each policy's mean curve over its episodes, with
//! the 95% interval of the mean as a band.
use anyhow::Result;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use umpnet_sim::scene::Task;

/// One policy's curve: per step, the mean over its episodes and the
/// half-width of the mean's 95% interval (normal approximation).
pub struct Curve {
    pub policy: String,
    pub episodes: usize,
    pub mean: Vec<f64>,
    pub half: Vec<f64>,
}

fn register_font() -> Result<()> {
    use std::sync::OnceLock;
    static FONT: OnceLock<std::result::Result<(), String>> = OnceLock::new();
    FONT.get_or_init(|| {
        let bytes = crate::text::FONT_PATHS
            .iter()
            .find_map(|p| std::fs::read(p).ok())
            .ok_or("no DejaVuSans.ttf found (apt-get install fonts-dejavu-core)")?;
        let leaked: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, leaked)
            .map_err(|_| "invalid font file".to_string())
    })
    .clone()
    .map_err(|e| anyhow::anyhow!(e))
}

/// "50 episodes each" when every policy has the same count, else each policy's.
pub fn episodes_text(curves: &[Curve]) -> String {
    let first = curves.first().map_or(0, |c| c.episodes);
    if curves.iter().all(|c| c.episodes == first) {
        format!("{first} episodes each")
    } else {
        let each: Vec<String> = curves
            .iter()
            .map(|c| format!("{} {}", c.policy, c.episodes))
            .collect();
        format!("episodes: {}", each.join(", "))
    }
}

const SIZE: (u32, u32) = (760, 500);
const PALETTE: [RGBColor; 5] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
];

/// Draws `curves` (unique states for exploration, normalized distance for the
/// goal task, against the step) on `root`; `about` says what they average.
fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    task: Task,
    curves: &[Curve],
    about: &str,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let steps = curves
        .iter()
        .map(|c| c.mean.len())
        .max()
        .unwrap_or(0)
        .max(2) as i32;
    let ymax = curves
        .iter()
        .flat_map(|c| c.mean.iter().zip(&c.half).map(|(m, h)| m + h))
        .fold(1.0, f64::max)
        * 1.05;
    let (title, ylabel) = match task {
        Task::Exploration => ("Exploration: unique states discovered", "unique states"),
        Task::Goal => (
            "Goal: normalized distance to the goal",
            "normalized distance",
        ),
    };
    let (top, rest) = root.split_vertically(52);
    top.draw(&Text::new(title, (14, 6), ("sans-serif", 22)))?;
    let subtitle = format!("mean and 95% interval; {about}");
    top.draw(&Text::new(subtitle, (14, 32), ("sans-serif", 14)))?;
    let mut chart = ChartBuilder::on(&rest)
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(56)
        .build_cartesian_2d(1i32..steps, 0f64..ymax)?;
    // Steps are whole numbers: one tick each (at most 20 labels).
    chart
        .configure_mesh()
        .x_desc("step")
        .y_desc(ylabel)
        .x_labels((steps as usize).min(20))
        .x_label_formatter(&|t| t.to_string())
        .draw()?;
    for (k, c) in curves.iter().enumerate() {
        let color = PALETTE.get(k % PALETTE.len()).copied().unwrap_or(BLACK);
        let upper = c.mean.iter().zip(&c.half).enumerate();
        let band: Vec<(i32, f64)> = upper
            .clone()
            .map(|(t, (m, h))| (t as i32 + 1, m + h))
            .chain(
                upper
                    .rev()
                    .map(|(t, (m, h))| (t as i32 + 1, (m - h).max(0.0))),
            )
            .collect();
        chart.draw_series(std::iter::once(Polygon::new(
            band,
            color.mix(0.18).filled(),
        )))?;
        chart
            .draw_series(LineSeries::new(
                c.mean.iter().enumerate().map(|(t, v)| (t as i32 + 1, *v)),
                color.stroke_width(3),
            ))?
            .label(c.policy.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(3))
            });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

/// Writes `out/curve.png` and `out/curve.svg`, each drawn in memory and
/// written atomically with the other results. Returns the names written.
pub fn plot_curves(
    task: Task,
    curves: &[Curve],
    about: &str,
    out: &Path,
) -> Result<Vec<&'static str>> {
    register_font()?;
    let (width, height) = SIZE;
    let mut pixels = vec![0u8; (width * height * 3) as usize];
    draw(
        &BitMapBackend::with_buffer(&mut pixels, SIZE).into_drawing_area(),
        task,
        curves,
        about,
    )?;
    let image = image::RgbImage::from_raw(width, height, pixels)
        .ok_or_else(|| anyhow::anyhow!("plot buffer of the wrong size"))?;
    crate::images::save(&image, &out.join("curve.png"))?;
    let mut svg = String::new();
    draw(
        &SVGBackend::with_string(&mut svg, SIZE).into_drawing_area(),
        task,
        curves,
        about,
    )?;
    umpnet_sim::fsio::write_atomic(&out.join("curve.svg"), svg.as_bytes())?;
    Ok(vec!["curve.png", "curve.svg"])
}
