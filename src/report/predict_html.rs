//! The `predict --html` page: what a machinist would rather look at than read.
//! A heat map of the predicted deviations over the part, the error vectors
//! magnified (as in the seed paper's Fig. 14(b)), a histogram, and the numbers.
use super::svg::{Chart, ChartSpec, ColourMap, HtmlPage, extent, histogram};
use crate::predict::PredictReport;

/// Render the self-contained HTML report.
pub fn render(report: &PredictReport, title: &str) -> String {
    let mut page = HtmlPage::new(title);
    let c = report.compensated;
    let pm = |u: Option<f64>| u.map_or(String::new(), |u| format!(" ± {u:.2}"));
    let (profile_u, range_u) = (
        pm(figure_u(report, c, false)),
        pm(figure_u(report, c, true)),
    );
    if c {
        // A compensated program: what the part will measure comes first.
        page.paragraph(&format!(
            "The program is compensated: the part will measure a profile error of {:.2}{profile_u} µm (twice the \
largest deviation, the compensated path's own offset included), range {:.2}{range_u} µm, over {} of {} plan \
points cut. Without compensation (the volumetric error along the surface normal at each point) it would be \
{:.2}{} µm.",
            report.profile_with_path_um,
            report.range_with_path_um,
            report.points_cut,
            report.points_total,
            report.profile_um,
            pm(report.profile_u_um)
        ));
    } else {
        page.paragraph(&format!(
            "Predicted profile error {:.2}{profile_u} µm (twice the largest deviation), range {:.2}{range_u} µm, \
over {} of {} plan points cut.",
            report.profile_um, report.range_um, report.points_cut, report.points_total
        ));
    }
    page.paragraph(&match report.rms_deviation_u_um {
        Some(u) => format!(
            "± is one standard uncertainty from the model's own noise (the error tables' measurement noise and \
the fit, {u:.3} µm RMS over the points); effects the model does not hold (backlash it was not told of, \
thermal drift, the probe) are not in it. The range's ± takes its two points' uncertainties as independent."
        ),
        None => "The model carries no uncertainties (a model file from before they were kept: refit it), \
so no ± is shown."
            .to_string(),
    });
    let cut: Vec<_> = report.points.iter().filter(|p| p.cut).collect();
    if !cut.is_empty() {
        page.figure(
            &deviation_map(report),
            if c {
                "What the part will measure over the part: the volumetric error along the surface normal plus how far the compensated path's contact point lies from the plan point along it (µm; red: material left, blue: cut too deep)."
            } else {
                "Predicted deviation over the part: the volumetric error along the surface normal at each plan point (µm; red: material left, blue: cut too deep)."
            },
        );
        page.figure(
            &vector_map(report),
            "Volumetric error vectors in the XY plane, magnified.",
        );
        let devs: Vec<f64> = cut.iter().filter_map(|p| p.shown_um(c)).collect();
        page.figure(
            &histogram(&devs, 24, "Predicted deviations", "deviation (µm)"),
            "Distribution of predicted deviations.",
        );
        let mut worst: Vec<_> = cut.clone();
        worst.sort_by(|a, b| {
            b.shown_um(c)
                .unwrap_or(0.0)
                .abs()
                .total_cmp(&a.shown_um(c).unwrap_or(0.0).abs())
        });
        page.heading("Largest predicted deviations");
        let rows: Vec<Vec<String>> = worst
            .iter()
            .take(15)
            .map(|p| {
                vec![
                    p.id.clone(),
                    format!(
                        "{:.3}{}",
                        p.shown_um(c).unwrap_or(0.0),
                        p.deviation_u_um
                            .map_or(String::new(), |u| format!(" ± {u:.3}"))
                    ),
                    p.deviation_u_um.map_or("-".into(), |u| format!("{u:.3}")),
                    p.line.map_or("-".into(), |l| l.to_string()),
                    format!("{:.2}, {:.2}, {:.2}", p.point[0], p.point[1], p.point[2]),
                ]
            })
            .collect();
        page.table(
            &[
                "id",
                "deviation µm",
                "standard uncertainty µm",
                "program line",
                "point (mm)",
            ],
            &rows,
        );
    }
    let not_cut: Vec<&str> = report
        .points
        .iter()
        .filter(|p| !p.cut)
        .map(|p| p.id.as_str())
        .collect();
    if !not_cut.is_empty() {
        page.heading("Plan points not cut");
        page.paragraph(&format!(
            "{} plan points have no tool-path point within {} mm of their contact point: {}",
            not_cut.len(),
            report.match_distance_mm,
            not_cut
                .iter()
                .take(50)
                .cloned()
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    page.finish()
}

/// The standard uncertainty of the page's profile error (`range`: of its
/// range) from the points that set it: twice the uncertainty of the largest
/// |deviation| shown; for the range, the largest and smallest deviation's
/// combined as independent. `None` when the model carries no uncertainties.
fn figure_u(report: &PredictReport, compensated: bool, range: bool) -> Option<f64> {
    let shown: Vec<(f64, f64)> = report
        .points
        .iter()
        .filter(|p| p.cut)
        .filter_map(|p| Some((p.shown_um(compensated)?, p.deviation_u_um?)))
        .collect();
    let by = |key: fn(&(f64, f64)) -> f64| {
        shown
            .iter()
            .copied()
            .max_by(|a, b| key(a).total_cmp(&key(b)))
    };
    if range {
        let (_, u_max) = by(|p| p.0)?;
        let (_, u_min) = by(|p| -p.0)?;
        Some(u_max.hypot(u_min))
    } else {
        by(|p| p.0.abs()).map(|(_, u)| 2.0 * u)
    }
}

fn part_chart(report: &PredictReport, title: &str) -> Chart {
    let xs = extent(report.points.iter().map(|p| p.point[0]), 0.06);
    let ys = extent(report.points.iter().map(|p| p.point[1]), 0.06);
    Chart::new(&ChartSpec {
        width: 640.0,
        height: 480.0,
        title,
        x_label: "x (mm, part)",
        y_label: "y (mm, part)",
        x_range: xs,
        y_range: ys,
        equal_aspect: true,
    })
}

fn deviation_map(report: &PredictReport) -> String {
    let c = report.compensated;
    let mut chart = part_chart(
        report,
        if c {
            "What the part will measure (µm)"
        } else {
            "Predicted deviation (µm)"
        },
    );
    let m = report
        .points
        .iter()
        .filter_map(|p| p.shown_um(c))
        .fold(0.0f64, |m, d| m.max(d.abs()))
        .max(1e-6);
    for p in &report.points {
        match p.shown_um(c) {
            Some(d) if p.cut => {
                let u = p
                    .deviation_u_um
                    .map_or(String::new(), |u| format!(" ± {u:.3}"));
                let label = format!("{}: {d:.3}{u} µm (line {})", p.id, p.line.unwrap_or(0));
                chart.point(
                    p.point[0],
                    p.point[1],
                    5.0,
                    &ColourMap::Diverging.colour(d, -m, m),
                    Some(&label),
                );
            }
            _ => chart.point(
                p.point[0],
                p.point[1],
                2.0,
                "#bbb",
                Some(&format!("{}: not cut", p.id)),
            ),
        }
    }
    chart.colour_bar(-m, m, ColourMap::Diverging, "µm");
    chart.finish()
}

fn vector_map(report: &PredictReport) -> String {
    let max_e = report
        .points
        .iter()
        .filter_map(|p| p.e_um)
        .map(|e| (e[0] * e[0] + e[1] * e[1]).sqrt())
        .fold(0.0f64, f64::max)
        .max(1e-9);
    let mut chart = part_chart(report, "");
    // The longest arrow is 24 px (about two plan-point spacings on a typical part);
    // the title says what that magnification is.
    let px_per_um = 24.0 / max_e;
    let magnification = px_per_um / chart.x.pixels_per_unit() * 1000.0;
    let title = format!("Error vectors (XY), magnified ×{magnification:.0}");
    chart
        .svg
        .text(chart.svg.width() / 2.0, 22.0, 14.0, "middle", &title);
    for p in &report.points {
        if let Some(e) = p.e_um {
            chart.point(p.point[0], p.point[1], 1.5, "#333", None);
            chart.arrow_pixels(
                p.point[0],
                p.point[1],
                e[0] * px_per_um,
                e[1] * px_per_um,
                "#1f5fa8",
            );
        }
    }
    chart.finish()
}
