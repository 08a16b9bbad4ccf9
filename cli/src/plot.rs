//! SVG line plots with `plotters`: a figure of side-by-side panels sharing axis labels.
//!
//! The SVG backend writes text as `<text>` elements, so no system fonts are needed.

use std::path::Path;

use anyhow::{anyhow, Context, Result};
pub use plotters::chart::SeriesLabelPosition;
use plotters::prelude::*;

/// Colours for successive series (Tableau 10).
pub const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// One curve.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend entry.
    pub label: String,
    /// Line colour.
    pub colour: RGBColor,
    /// Points (x, y) in plot units.
    pub points: Vec<(f64, f64)>,
    /// Dashed (reference lines) rather than solid.
    pub dashed: bool,
}

/// One panel of a figure.
#[derive(Debug, Clone, Default)]
pub struct Panel {
    /// Caption above the panel.
    pub title: String,
    /// The curves.
    pub series: Vec<Series>,
    /// Where the legend goes (default: upper left, with head room kept free for it).
    pub legend: Option<SeriesLabelPosition>,
}

/// A figure: panels side by side.
#[derive(Debug, Clone, Default)]
pub struct Figure {
    /// Label of the x axis, with unit.
    pub x_label: String,
    /// Label of the y axis, with unit.
    pub y_label: String,
    /// The panels, left to right.
    pub panels: Vec<Panel>,
}

const PANEL_WIDTH: u32 = 520;
const HEIGHT: u32 = 440;

/// Write `figure` as an SVG file at `path`.
pub fn write_svg(path: &Path, figure: &Figure) -> Result<()> {
    let svg = svg_string(figure).with_context(|| format!("cannot draw plot {}", path.display()))?;
    std::fs::write(path, svg).with_context(|| format!("cannot write plot {}", path.display()))
}

/// `figure` as the text of an SVG document (an `<svg>` element, which HTML also takes
/// inline).
pub fn svg_string(figure: &Figure) -> Result<String> {
    let n = figure.panels.len().max(1);
    let width = PANEL_WIDTH * n as u32;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (width, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_error)?;
        let areas = root.split_evenly((1, n));
        for (panel, area) in figure.panels.iter().zip(&areas) {
            draw_panel(area, panel, figure)?;
        }
        root.present().map_err(plot_error)?;
    }
    Ok(svg)
}

fn plot_error<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow!("{e}")
}

fn draw_panel(
    area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    panel: &Panel,
    figure: &Figure,
) -> Result<()> {
    let (x_range, mut y_range) = ranges(panel);
    let legend = panel
        .legend
        .clone()
        .unwrap_or(SeriesLabelPosition::UpperLeft);
    if legend == SeriesLabelPosition::UpperLeft {
        // Head room for the legend above the curves.
        y_range.end += 0.2 * (y_range.end - y_range.start);
    }
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d(x_range, y_range)
        .map_err(plot_error)?;
    chart
        .configure_mesh()
        .x_desc(figure.x_label.as_str())
        .y_desc(figure.y_label.as_str())
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(plot_error)?;
    for s in &panel.series {
        let colour = s.colour;
        let style = colour.stroke_width(if s.dashed { 1 } else { 2 });
        let anno = if s.dashed {
            chart
                .draw_series(DashedLineSeries::new(s.points.iter().copied(), 6, 4, style))
                .map_err(plot_error)?
        } else {
            chart
                .draw_series(LineSeries::new(s.points.iter().copied(), style))
                .map_err(plot_error)?
        };
        anno.label(s.label.as_str()).legend(move |(x, y)| {
            PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
        });
    }
    if panel.series.iter().any(|s| !s.label.is_empty()) {
        chart
            .configure_series_labels()
            .position(legend)
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(180, 180, 180))
            .draw()
            .map_err(plot_error)?;
    }
    Ok(())
}

/// Axis ranges covering every finite point of the panel, with 5 % padding.
fn ranges(panel: &Panel) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let points = panel
        .series
        .iter()
        .flat_map(|s| s.points.iter())
        .filter(|(x, y)| x.is_finite() && y.is_finite());
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in points {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    (pad(x0, x1), pad(y0, y1))
}

fn pad(lo: f64, hi: f64) -> std::ops::Range<f64> {
    if !(lo.is_finite() && hi.is_finite()) {
        return -1.0..1.0;
    }
    let span = hi - lo;
    let margin = if span > 0.0 {
        0.05 * span
    } else {
        0.5 * lo.abs().max(1.0)
    };
    (lo - margin)..(hi + margin)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_are_padded_and_never_empty() {
        assert_eq!(pad(0.0, 10.0), -0.5..10.5);
        let r = pad(3.0, 3.0);
        assert!(r.start < 3.0 && r.end > 3.0);
        assert_eq!(pad(f64::INFINITY, f64::NEG_INFINITY), -1.0..1.0);
    }
}
