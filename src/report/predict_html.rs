//! The `predict --html` page: what a machinist would rather look at than read.
//! A heat map of the predicted deviations over the part, the error vectors
//! magnified (as in the seed paper's Fig. 14(b)), a histogram, and the numbers.
use super::svg::{Chart, ChartSpec, ColourMap, HtmlPage, extent, histogram};
use crate::predict::PredictReport;

/// Render the self-contained HTML report.
pub fn render(report: &PredictReport, title: &str) -> String {
    let mut page = HtmlPage::new(title);
    let c = report.compensated;
    if c {
        // A compensated program: what the part will measure comes first.
        page.paragraph(&format!(
            "The program is compensated: the part will measure a profile error of {:.2} µm (2·max|d|, \
the compensated path's own offset included), range {:.2} µm, over {} of {} plan points cut. \
Without compensation (n·e as formats.md defines it) it would be {:.2} µm{}.",
            report.profile_with_path_um,
            report.range_with_path_um,
            report.points_cut,
            report.points_total,
            report.profile_um,
            report
                .profile_u_um
                .map_or(String::new(), |u| format!(" ± {u:.2}"))
        ));
    } else {
        page.paragraph(&format!(
            "Predicted profile error {:.2} µm (2·max|d|), range {:.2} µm, over {} of {} plan points cut.",
            report.profile_um, report.range_um, report.points_cut, report.points_total
        ));
    }
    let cut: Vec<_> = report.points.iter().filter(|p| p.cut).collect();
    if !cut.is_empty() {
        page.figure(
            &deviation_map(report),
            if c {
                "What the part will measure, n·e + n·(c − p), over the part (µm; red: material left, blue: cut too deep)."
            } else {
                "Predicted deviation n·e over the part (µm; red: material left, blue: cut too deep)."
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
                    format!("{:.3}", p.shown_um(c).unwrap_or(0.0)),
                    p.line.map_or("-".into(), |l| l.to_string()),
                    format!("{:.2}, {:.2}, {:.2}", p.point[0], p.point[1], p.point[2]),
                ]
            })
            .collect();
        page.table(&["id", "deviation µm", "program line", "point (mm)"], &rows);
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
                let label = format!("{}: {:.3} µm (line {})", p.id, d, p.line.unwrap_or(0));
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
