//! curve.png: the mean curve of each policy over its episodes.
use anyhow::Result;
use std::path::Path;
use umpnet_sim::scene::Task;

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

/// Mean curve per policy (`curves`, in the policies' order): unique states
/// (exploration) or normalized distance (goal) vs step.
pub fn plot_curves(task: Task, curves: &[(String, Vec<f64>)], path: &Path) -> Result<()> {
    use plotters::prelude::*;
    register_font()?;
    let max_len = curves.iter().map(|(_, c)| c.len()).max().unwrap_or(0);
    let ymax = curves
        .iter()
        .flat_map(|(_, c)| c.iter().copied())
        .fold(1.0, f64::max)
        * 1.05;
    let (width, height) = (720u32, 480u32);
    // Drawn in memory, written atomically with the other results.
    let mut pixels = vec![0u8; (width * height * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, (width, height)).into_drawing_area();
        root.fill(&WHITE)?;
        let (title, ylabel) = match task {
            Task::Exploration => ("Exploration: unique states discovered", "unique states"),
            Task::Goal => (
                "Goal: normalized distance to the goal",
                "normalized distance",
            ),
        };
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(56)
            .build_cartesian_2d(1f64..max_len.max(2) as f64, 0f64..ymax)?;
        chart
            .configure_mesh()
            .x_desc("step")
            .y_desc(ylabel)
            .draw()?;
        let palette = [
            RGBColor(31, 119, 180),
            RGBColor(214, 39, 40),
            RGBColor(44, 160, 44),
            RGBColor(148, 103, 189),
            RGBColor(255, 127, 14),
        ];
        for (k, (name, c)) in curves.iter().enumerate() {
            let color = palette.get(k % palette.len()).copied().unwrap_or(BLACK);
            chart
                .draw_series(LineSeries::new(
                    c.iter().enumerate().map(|(t, v)| ((t + 1) as f64, *v)),
                    color.stroke_width(3),
                ))?
                .label(name.clone())
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
    }
    let image = image::RgbImage::from_raw(width, height, pixels)
        .ok_or_else(|| anyhow::anyhow!("plot buffer of the wrong size"))?;
    crate::images::save(&image, path)
}
