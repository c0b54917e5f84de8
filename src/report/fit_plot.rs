//! SVG plot of one fitted parameter, like the paper's Fig. 3 / Fig. 11: the
//! measured points, the fitted curve and the knot positions (dashed verticals at
//! `x(u_j)` of each distinct interior knot). Pure: returns the SVG text.
use super::svg::{Chart, ChartSpec, extent};
use crate::nurbs::SmemCurve;
use crate::nurbs::knot_vector;

/// Labels of a plot.
pub struct PlotLabels<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
}

/// The SVG of `curve` against its data.
pub fn plot_fit(
    positions: &[f64],
    values: &[f64],
    curve: &SmemCurve,
    labels: &PlotLabels<'_>,
) -> String {
    let (x0, x1) = curve.domain();
    let samples = 400;
    let line: Vec<(f64, f64)> = (0..=samples)
        .map(|i| {
            let x = x0 + (x1 - x0) * i as f64 / samples as f64;
            (x, curve.value_at(x))
        })
        .collect();
    let y_range = extent(values.iter().copied().chain(line.iter().map(|p| p.1)), 0.08);
    let mut chart = Chart::new(&ChartSpec {
        width: 720.0,
        height: 420.0,
        title: labels.title,
        x_label: labels.x_label,
        y_label: labels.y_label,
        x_range: (x0, x1),
        y_range,
        equal_aspect: false,
    });
    let mut interior = knot_vector::interior(curve.knots(), curve.degree()).to_vec();
    interior.dedup();
    for u in interior {
        let x = curve.curve().eval(u)[0];
        chart.vertical_marker(x, "#c0392b");
    }
    chart.polyline(&line, "#1f5fa8", 1.8);
    for (&x, &y) in positions.iter().zip(values) {
        let e = y - curve.value_at(x);
        let title = format!("{x}: {y} (residual {e:.3})");
        chart.point(x, y, 3.0, "#222", Some(&title));
    }
    chart.legend(&[
        ("#222", "discrete points"),
        ("#1f5fa8", "fitted curve"),
        ("#c0392b", "knots"),
    ]);
    chart.finish()
}
