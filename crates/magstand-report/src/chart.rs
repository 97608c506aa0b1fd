//! The two kinds of figure every page uses, drawn with plotters into SVG text: x-y charts
//! (lines, points, shaded bands) and grids of histograms with a normal curve over them.
//!
//! Colours come from the Okabe-Ito palette, which stays distinguishable with the common forms of
//! colour blindness; series also differ in line style or marker where that helps.
use plotters::prelude::*;

use crate::ReportError;

/// Okabe-Ito colours, in the order series use them.
pub const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),   // blue
    RGBColor(230, 159, 0),   // orange
    RGBColor(0, 158, 115),   // bluish green
    RGBColor(213, 94, 0),    // vermillion
    RGBColor(204, 121, 167), // reddish purple
    RGBColor(86, 180, 233),  // sky blue
    RGBColor(240, 228, 66),  // yellow
    RGBColor(0, 0, 0),       // black
];

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mark {
    /// A line through the points.
    Line,
    /// A dashed line (e.g. a model next to data).
    Dashed,
    /// Small dots (data).
    Dots,
}

/// One series of an x-y chart.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Points.
    pub points: Vec<(f64, f64)>,
    /// Shaded band `(x, low, high)` drawn under the series.
    pub band: Vec<(f64, f64, f64)>,
    /// How it is drawn.
    pub mark: Mark,
    /// Index into [`PALETTE`].
    pub colour: usize,
}

impl Series {
    /// A line.
    pub fn line(label: impl Into<String>, points: Vec<(f64, f64)>, colour: usize) -> Self {
        Self {
            label: label.into(),
            points,
            band: Vec::new(),
            mark: Mark::Line,
            colour,
        }
    }

    /// Dots.
    pub fn dots(label: impl Into<String>, points: Vec<(f64, f64)>, colour: usize) -> Self {
        Self {
            mark: Mark::Dots,
            ..Self::line(label, points, colour)
        }
    }

    /// The same series with a shaded band.
    pub fn with_band(mut self, band: Vec<(f64, f64, f64)>) -> Self {
        self.band = band;
        self
    }

    /// The same series drawn dashed.
    pub fn dashed(mut self) -> Self {
        self.mark = Mark::Dashed;
        self
    }
}

/// An x-y chart.
#[derive(Debug, Clone)]
pub struct XyChart {
    /// File-like name, used in errors and as the SVG's id.
    pub name: String,
    /// Title above the plot.
    pub title: String,
    /// X axis quantity and unit.
    pub x_label: String,
    /// Y axis quantity and unit.
    pub y_label: String,
    /// Series, drawn in order.
    pub series: Vec<Series>,
    /// Size in pixels.
    pub size: (u32, u32),
}

fn draw_err(name: &str) -> impl Fn(Box<dyn std::error::Error + '_>) -> ReportError + '_ {
    move |e| ReportError::Draw {
        figure: name.to_string(),
        message: e.to_string(),
    }
}

fn bounds(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return None;
    }
    // A flat series still gets a visible axis; otherwise 5 % margins.
    let pad = if hi > lo {
        0.05 * (hi - lo)
    } else {
        lo.abs().max(1.0) * 0.1
    };
    Some((lo - pad, hi + pad))
}

impl XyChart {
    /// A chart with no series yet.
    pub fn new(name: &str, title: &str, x_label: &str, y_label: &str) -> Self {
        Self {
            name: name.into(),
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            series: Vec::new(),
            size: (720, 420),
        }
    }

    /// Adds a series.
    pub fn with(mut self, s: Series) -> Self {
        self.series.push(s);
        self
    }

    /// Draws the chart as SVG text.
    pub fn to_svg(&self) -> Result<String, ReportError> {
        let xs = self.series.iter().flat_map(|s| {
            s.points
                .iter()
                .map(|p| p.0)
                .chain(s.band.iter().map(|b| b.0))
        });
        let ys = self.series.iter().flat_map(|s| {
            s.points
                .iter()
                .map(|p| p.1)
                .chain(s.band.iter().flat_map(|b| [b.1, b.2]))
        });
        let empty = || ReportError::Empty {
            figure: self.name.clone(),
            message: "no finite values to draw".into(),
        };
        let (x0, x1) = bounds(xs).ok_or_else(empty)?;
        let (y0, y1) = bounds(ys).ok_or_else(empty)?;
        let mut svg = String::new();
        {
            let e = draw_err(&self.name);
            let root = SVGBackend::with_string(&mut svg, self.size).into_drawing_area();
            root.fill(&WHITE).map_err(|x| e(Box::new(x)))?;
            let mut chart = ChartBuilder::on(&root)
                .caption(&self.title, ("sans-serif", 18))
                .margin(12)
                .x_label_area_size(42)
                .y_label_area_size(64)
                .build_cartesian_2d(x0..x1, y0..y1)
                .map_err(|x| e(Box::new(x)))?;
            chart
                .configure_mesh()
                .x_desc(&self.x_label)
                .y_desc(&self.y_label)
                .light_line_style(RGBColor(235, 235, 235))
                .draw()
                .map_err(|x| e(Box::new(x)))?;
            for s in &self.series {
                let c = PALETTE[s.colour % PALETTE.len()];
                if s.band.len() >= 2 {
                    let mut poly: Vec<(f64, f64)> = s.band.iter().map(|b| (b.0, b.2)).collect();
                    poly.extend(s.band.iter().rev().map(|b| (b.0, b.1)));
                    chart
                        .draw_series(std::iter::once(Polygon::new(poly, c.mix(0.18).filled())))
                        .map_err(|x| e(Box::new(x)))?;
                }
                let pts: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|p| p.0.is_finite() && p.1.is_finite())
                    .collect();
                let anno = match s.mark {
                    Mark::Line => chart
                        .draw_series(LineSeries::new(pts, c.stroke_width(2)))
                        .map_err(|x| e(Box::new(x)))?,
                    Mark::Dashed => chart
                        .draw_series(DashedLineSeries::new(pts, 8, 5, c.stroke_width(2)))
                        .map_err(|x| e(Box::new(x)))?,
                    Mark::Dots => chart
                        .draw_series(pts.into_iter().map(|p| Circle::new(p, 1, c.filled())))
                        .map_err(|x| e(Box::new(x)))?,
                };
                if !s.label.is_empty() {
                    anno.label(&s.label).legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(3))
                    });
                }
            }
            if self.series.iter().any(|s| !s.label.is_empty()) {
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.85))
                    .border_style(RGBColor(180, 180, 180))
                    .position(SeriesLabelPosition::UpperLeft)
                    .draw()
                    .map_err(|x| e(Box::new(x)))?;
            }
            root.present().map_err(|x| e(Box::new(x)))?;
        }
        Ok(svg)
    }
}

/// One histogram panel, optionally with a normal density over it (scaled to the counts).
#[derive(Debug, Clone)]
pub struct HistogramPanel {
    /// Panel title (the quantity).
    pub title: String,
    /// The values.
    pub values: Vec<f64>,
    /// Mean and sd of the normal curve to draw over the bars.
    pub normal: Option<(f64, f64)>,
}

/// Draws histogram panels in a grid of `columns` as SVG text.
pub fn histogram_grid(
    name: &str,
    title: &str,
    x_label: &str,
    panels: &[HistogramPanel],
    columns: usize,
) -> Result<String, ReportError> {
    if panels.is_empty() {
        return Err(ReportError::Empty {
            figure: name.into(),
            message: "no panels".into(),
        });
    }
    let columns = columns.max(1);
    let rows = panels.len().div_ceil(columns);
    let mut svg = String::new();
    {
        let e = draw_err(name);
        let root =
            SVGBackend::with_string(&mut svg, (220 * columns as u32, 190 * rows as u32 + 40))
                .into_drawing_area();
        root.fill(&WHITE).map_err(|x| e(Box::new(x)))?;
        let root = root
            .titled(title, ("sans-serif", 18))
            .map_err(|x| e(Box::new(x)))?;
        let areas = root.split_evenly((rows, columns));
        for (panel, area) in panels.iter().zip(areas.iter()) {
            let v: Vec<f64> = panel
                .values
                .iter()
                .copied()
                .filter(|x| x.is_finite())
                .collect();
            let Some((lo, hi)) = bounds(
                v.iter().copied().chain(
                    panel
                        .normal
                        .iter()
                        .flat_map(|(m, s)| [m - 3.0 * s, m + 3.0 * s]),
                ),
            ) else {
                continue;
            };
            let bins = ((v.len() as f64).sqrt().ceil() as usize).clamp(5, 40);
            let width = (hi - lo) / bins as f64;
            let mut counts = vec![0usize; bins];
            for x in &v {
                counts[(((x - lo) / width) as usize).min(bins - 1)] += 1;
            }
            let peak_normal = panel
                .normal
                .map(|(_, s)| v.len() as f64 * width / (s * (std::f64::consts::TAU).sqrt()))
                .unwrap_or(0.0);
            let top = (*counts.iter().max().unwrap_or(&1) as f64).max(peak_normal) * 1.1;
            let mut chart = ChartBuilder::on(area)
                .caption(&panel.title, ("sans-serif", 13))
                .margin(6)
                .x_label_area_size(28)
                .y_label_area_size(34)
                .build_cartesian_2d(lo..hi, 0.0..top.max(1.0))
                .map_err(|x| e(Box::new(x)))?;
            chart
                .configure_mesh()
                .x_labels(4)
                .y_labels(4)
                .x_desc(x_label)
                .light_line_style(RGBColor(240, 240, 240))
                .draw()
                .map_err(|x| e(Box::new(x)))?;
            chart
                .draw_series(counts.iter().enumerate().map(|(i, &c)| {
                    let x0 = lo + i as f64 * width;
                    Rectangle::new(
                        [(x0, 0.0), (x0 + width, c as f64)],
                        PALETTE[0].mix(0.6).filled(),
                    )
                }))
                .map_err(|x| e(Box::new(x)))?;
            if let Some((m, s)) = panel.normal {
                let curve = (0..=100).map(|i| {
                    let x = lo + (hi - lo) * i as f64 / 100.0;
                    let z = (x - m) / s;
                    (x, peak_normal * (-0.5 * z * z).exp())
                });
                chart
                    .draw_series(LineSeries::new(curve, PALETTE[3].stroke_width(2)))
                    .map_err(|x| e(Box::new(x)))?;
            }
        }
        root.present().map_err(|x| e(Box::new(x)))?;
    }
    Ok(svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chart_has_its_labels_series_and_band() {
        let svg = XyChart::new("t", "Title here", "throttle (0..1)", "error (µT)")
            .with(
                Series::line("model", vec![(0.0, 1.0), (1.0, 2.0)], 0)
                    .with_band(vec![(0.0, 0.5, 1.5), (1.0, 1.5, 2.5)]),
            )
            .with(Series::dots("data", vec![(0.5, 1.4)], 1))
            .to_svg()
            .unwrap();
        for needle in [
            "Title here",
            "throttle (0..1)",
            "error (µT)",
            "model",
            "data",
            "<polygon",
            "<circle",
        ] {
            assert!(svg.contains(needle), "missing {needle}");
        }
    }

    #[test]
    fn a_chart_without_finite_values_is_an_error_not_a_blank_figure() {
        let e = XyChart::new("empty", "t", "x", "y")
            .with(Series::line("nan", vec![(f64::NAN, 1.0)], 0))
            .to_svg()
            .unwrap_err()
            .to_string();
        assert!(e.contains("empty") && e.contains("no finite"), "{e}");
    }

    #[test]
    fn histogram_counts_add_up_and_the_curve_is_drawn() {
        let values: Vec<f64> = (0..400)
            .map(|i| ((i * 37) % 101) as f64 / 50.0 - 1.0)
            .collect();
        let svg = histogram_grid(
            "h",
            "Errors",
            "error (µT)",
            &[HistogramPanel {
                title: "x.a1".into(),
                values,
                normal: Some((0.0, 0.5)),
            }],
            1,
        )
        .unwrap();
        assert!(svg.contains("x.a1") && svg.contains("<rect") && svg.contains("<polyline"));
    }
}
