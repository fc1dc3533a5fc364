//! `bench --plot`: time per ray against triangle count on log-log axes, as SVG through the
//! `plotters` crate's SVG backend (text stays `<text>`, so no font files are needed and the
//! README shows the plot sharp at any size).
//!
//! The generated meshes (a seeded bumpy sphere of growing size) are the two lines, BVH and
//! linear scan; models measured beside them are triangle markers of the same colours.

use crate::tools::bench::Row;
use plotters::prelude::*;

const WIDTH: u32 = 880;
const HEIGHT: u32 = 600;
const BVH_COLOR: RGBColor = RGBColor(30, 90, 200);
const LINEAR_COLOR: RGBColor = RGBColor(210, 60, 40);

/// One series: (triangles, nanoseconds per ray per thread) for every row that has a value.
fn points(rows: &[Row], value: impl Fn(&Row) -> Option<f64>) -> Vec<(f64, f64)> {
    rows.iter()
        .filter_map(|r| value(r).map(|v| (r.triangles.max(1) as f64, v.max(1e-3))))
        .collect()
}

/// The SVG document of the plot of nanoseconds per ray (per thread) against triangles for the
/// BVH and the linear scan: `generated` rows as lines with points, `models` as triangle markers.
pub fn scaling_plot(generated: &[Row], models: &[Row], title: &str) -> Result<String, PlotError> {
    let bvh = points(generated, |r| Some(r.bvh_ns_per_ray()));
    let linear = points(generated, Row::linear_ns_per_ray);
    let model_bvh = points(models, |r| Some(r.bvh_ns_per_ray()));
    let model_linear = points(models, Row::linear_ns_per_ray);
    let all = || {
        bvh.iter()
            .chain(&linear)
            .chain(&model_bvh)
            .chain(&model_linear)
    };
    let (x_lo, x_hi) = decades(all().map(|p| p.0));
    let (y_lo, y_hi) = decades(all().map(|p| p.1));
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_error)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 24))
            .margin(20)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d((x_lo..x_hi).log_scale(), (y_lo..y_hi).log_scale())
            .map_err(draw_error)?;
        chart
            .configure_mesh()
            .x_desc("triangles")
            .y_desc("ns per ray per thread")
            .x_label_formatter(&|v| format!("{v:.0e}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .label_style(("sans-serif", 16))
            .axis_desc_style(("sans-serif", 18))
            .light_line_style(RGBColor(240, 240, 240))
            .draw()
            .map_err(draw_error)?;
        for (series, color, name) in [
            (&linear, LINEAR_COLOR, "linear scan, O(n)"),
            (&bvh, BVH_COLOR, "BVH, O(log n)"),
        ] {
            chart
                .draw_series(LineSeries::new(
                    series.iter().copied(),
                    color.stroke_width(3),
                ))
                .map_err(draw_error)?
                .label(name)
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 20, y)], color.stroke_width(3))
                });
            chart
                .draw_series(series.iter().map(|&p| Circle::new(p, 5, color.filled())))
                .map_err(draw_error)?;
        }
        for (series, color, name) in [
            (&model_linear, LINEAR_COLOR, "linear scan, models"),
            (&model_bvh, BVH_COLOR, "BVH, models"),
        ] {
            if series.is_empty() {
                continue;
            }
            chart
                .draw_series(
                    series
                        .iter()
                        .map(|&p| TriangleMarker::new(p, 7, color.stroke_width(2))),
                )
                .map_err(draw_error)?
                .label(name)
                .legend(move |(x, y)| TriangleMarker::new((x + 10, y), 7, color.stroke_width(2)));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .label_font(("sans-serif", 16))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK.mix(0.3))
            .draw()
            .map_err(draw_error)?;
        root.present().map_err(draw_error)?;
    }
    Ok(svg)
}

/// A drawing error of plotters (drawing into a string fails only on a plotting bug).
#[derive(Debug, thiserror::Error)]
#[error("drawing the plot: {0}")]
pub struct PlotError(String);

fn draw_error<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> PlotError {
    PlotError(e.to_string())
}

/// Whole decades around the values (powers of ten), at least one decade wide.
fn decades(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.map(f64::log10) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() || !hi.is_finite() {
        return (1.0, 10.0);
    }
    let (lo, hi) = (lo.floor(), hi.ceil());
    let hi = if hi > lo { hi } else { lo + 1.0 };
    (10f64.powf(lo), 10f64.powf(hi))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn row(name: &str, triangles: usize, bvh_mrays: f64, linear_mrays: Option<f64>) -> Row {
        Row {
            name: name.into(),
            kind: crate::tools::bench::RayKind::Primary,
            triangles,
            build: Duration::ZERO,
            bvh_mrays,
            bvh_run_mrays: vec![bvh_mrays],
            linear_mrays,
            rays: 1,
            threads: 2,
            build_steps: Vec::new(),
            soup_bytes: 0,
            accel_bytes: 0,
        }
    }

    /// Whether the SVG has a `<text>` element of exactly `text` (plotters writes the text on
    /// its own line between the tags).
    fn has_text(svg: &str, text: &str) -> bool {
        svg.contains(&format!(">\n{text}\n</text>"))
    }

    #[test]
    fn the_axes_span_whole_decades_around_the_data() {
        assert_eq!(decades([1024.0, 1e6].into_iter()), (1e3, 1e6));
        assert_eq!(decades([135.0, 1.4e7].into_iter()), (1e2, 1e8));
        assert_eq!(decades([100.0].into_iter()), (1e2, 1e3));
        assert_eq!(decades(std::iter::empty()), (1.0, 10.0));
    }

    #[test]
    fn the_plot_is_an_svg_with_both_series_and_its_labels() {
        let generated = [
            row("generated 1000", 1024, 14.78, Some(0.3243)),
            row("generated 1000000", 1_000_000, 5.06, Some(0.0001)),
        ];
        let models = [row("DamagedHelmet.gltf", 15452, 10.99, None)];
        let svg = scaling_plot(&generated, &models, "time per primary ray vs triangles").unwrap();
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        for text in [
            "time per primary ray vs triangles",
            "triangles",
            "ns per ray per thread",
            "BVH, O(log n)",
            "linear scan, O(n)",
            "BVH, models",
            "1e3",
            "1e6",
        ] {
            assert!(has_text(&svg, text), "{text}");
        }
        assert!(
            !has_text(&svg, "linear scan, models"),
            "no model was scanned"
        );
        // Two lines (polylines) in the two colours, four filled points.
        assert!(svg.matches("<polyline").count() >= 2);
        assert!(
            svg.contains("#1E5AC8") || svg.contains("#1e5ac8"),
            "BVH blue"
        );
        assert!(
            svg.contains("#D23C28") || svg.contains("#d23c28"),
            "linear red"
        );
        assert_eq!(svg.matches("<circle").count(), 4);
    }

    #[test]
    fn an_empty_measurement_still_draws_axes() {
        let svg = scaling_plot(&[], &[], "empty").unwrap();
        assert!(has_text(&svg, "empty"));
        assert!(has_text(&svg, "triangles"));
    }
}
