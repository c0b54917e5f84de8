//! `diagnose --html`: a self-contained page with residual maps over the part
//! (before and after the selected effects), residual vs time, A and C, the
//! effects table and the summary.
//!
//! Invariant: pure string building from the report (no I/O).
use super::svg::{Chart, ChartSpec, ColourMap, HtmlPage, extent};
use crate::diagnose::EffectKind;
use crate::diagnose::followup::Separation;
use crate::diagnose::report::{DiagnoseReport, PointResidual};

fn residual_map(report: &DiagnoseReport, after: bool, lim: f64) -> String {
    let res = &report.residuals;
    let x = extent(res.iter().map(|p| p.point[0]), 0.05);
    let y = extent(res.iter().map(|p| p.point[1]), 0.05);
    let title = if after {
        "Residual after the selected effects"
    } else {
        "Residual: measured − predicted"
    };
    let mut chart = Chart::new(&ChartSpec {
        width: 520.0,
        height: 420.0,
        title,
        x_label: "x (mm)",
        y_label: "y (mm)",
        x_range: x,
        y_range: y,
        equal_aspect: true,
    });
    for p in res {
        let v = if after {
            p.residual_after_um
        } else {
            p.residual_um
        };
        let colour = ColourMap::Diverging.colour(v, -lim, lim);
        let label = format!("{}: {:.2} µm", p.id, v);
        chart.point(p.point[0], p.point[1], 4.0, &colour, Some(&label));
    }
    chart.colour_bar(-lim, lim, ColourMap::Diverging, "µm");
    chart.finish()
}

fn scatter(
    report: &DiagnoseReport,
    key: impl Fn(&PointResidual) -> f64,
    title: &str,
    x_label: &str,
) -> String {
    let res = &report.residuals;
    let xr = extent(res.iter().map(&key), 0.03);
    let yr = extent(
        res.iter()
            .flat_map(|p| [p.residual_um, p.residual_after_um]),
        0.08,
    );
    let mut chart = Chart::new(&ChartSpec {
        width: 520.0,
        height: 300.0,
        title,
        x_label,
        y_label: "residual (µm)",
        x_range: xr,
        y_range: yr,
        equal_aspect: false,
    });
    for p in res {
        chart.point(key(p), p.residual_um, 2.5, "#b2182b", None);
        chart.point(key(p), p.residual_after_um, 2.0, "#2166ac", None);
    }
    chart.legend(&[("#b2182b", "before"), ("#2166ac", "after")]);
    chart.finish()
}

/// The unit of parameter `name` of `kind` (rotary-location names of any
/// machine: `E` + X/Y/Z is an offset in µm, + A/B/C a tilt in µrad).
fn unit_of(kind: EffectKind, name: &str) -> &'static str {
    if let Some(i) = kind.parameters().iter().position(|p| *p == name) {
        return kind.units().get(i).copied().unwrap_or("");
    }
    match name.chars().nth(1) {
        Some('X' | 'Y' | 'Z') => "µm",
        Some('A' | 'B' | 'C') => "µrad",
        _ => "",
    }
}

/// The HTML page of a report: one section after another, in the order a
/// reader asks (how large is the gap, is the model right, which effect, where).
pub fn render(report: &DiagnoseReport) -> String {
    let mut page = HtmlPage::new("volcomp diagnose: the sim-to-real gap");
    summary_section(&mut page, report);
    model_section(&mut page, report);
    parameters_section(&mut page, report);
    anomalies_section(&mut page, report);
    effects_section(&mut page, report);
    residual_plots_section(&mut page, report);
    localisation_section(&mut page, report);
    followup_sections(&mut page, report);
    page.heading("Selection");
    page.preformatted(&report.selection_notes.join("\n"));
    page.finish()
}

/// The summary sentences and the gap, before and after the selected effects.
fn summary_section(page: &mut HtmlPage, report: &DiagnoseReport) {
    page.heading("Summary");
    for s in &report.summary {
        page.paragraph(s);
    }
    let g = &report.gap;
    page.table(
        &[
            "points",
            "used",
            "measured profile µm",
            "predicted profile µm",
            "residual RMS µm",
            "noise floor µm",
            "after: profile µm",
            "after: residual RMS µm",
        ],
        &[vec![
            report.points.to_string(),
            report.points_used.to_string(),
            format!("{:.2}", g.measured_profile_um),
            format!("{:.2}", g.predicted_profile_um),
            format!("{:.3}", g.residual_rms_um),
            format!("{:.3} ({})", g.noise_floor_um, g.noise_floor_source),
            format!("{:.2}", report.after.predicted_profile_um),
            format!("{:.3}", report.after.residual_rms_um),
        ]],
    );
}

/// The verdict on the machine's error model and its axis factors.
fn model_section(page: &mut HtmlPage, report: &DiagnoseReport) {
    let m = &report.model_check;
    page.heading("The error model");
    let verdict = if !m.mismatch {
        "consistent with the measurement"
    } else if m.follows_model {
        "does not match: tables scaled or stale"
    } else {
        "does not match: the gap stays unexplained"
    };
    page.table(
        &[
            "verdict",
            "axis factors (machine ÷ model)",
            "remaining RMS µm",
            "noise + model uncertainty µm",
            "model uncertainty µm",
            "uncertainty would be ×",
        ],
        &[vec![
            verdict.to_string(),
            factors_cell(m),
            format!("{:.3}", m.remaining_rms_um),
            format!("{:.3}", m.expected_rms_um),
            format!("{:.3}", m.model_uncertainty_um),
            m.uncertainty_factor
                .map_or(String::new(), |f| format!("{f:.1}")),
        ]],
    );
}

/// The model's axis factors: the selection's when the model is in it; else
/// said to be the model fitted alone, which the evidence did not select (a
/// reader must not take them for the machine's scale).
fn factors_cell(m: &crate::diagnose::report::ModelCheck) -> String {
    let factors = m
        .factors
        .iter()
        .map(|(k, b)| format!("{k} ×{:.2}", 1.0 + b))
        .collect::<Vec<_>>()
        .join(", ");
    if m.follows_model || factors.is_empty() {
        factors
    } else {
        format!("not selected (the model fitted alone: {factors})")
    }
}

/// "yes" or "no".
fn yes_no(b: bool) -> String {
    if b { "yes" } else { "no" }.to_string()
}

/// The selected effects' parameters: value ± σ, unit, identifiable, plausible.
fn parameters_section(page: &mut HtmlPage, report: &DiagnoseReport) {
    if report.after.checks.is_empty() {
        return;
    }
    page.heading("Selected effects: parameters (joint fit, ± one standard uncertainty)");
    let rows: Vec<Vec<String>> = report
        .after
        .checks
        .iter()
        .flat_map(|(effect, list)| {
            let z = report.after.significance.get(effect).copied();
            list.iter().map(move |c| {
                vec![
                    effect.clone(),
                    z.map_or(String::new(), |z| format!("{z:.0}")),
                    c.name.clone(),
                    if c.unit == "s²" {
                        format!("{:.3e} ± {:.1e}", c.value, c.std)
                    } else {
                        format!("{:.3} ± {:.3}", c.value, c.std)
                    },
                    c.unit.clone(),
                    yes_no(c.identifiable),
                    yes_no(c.plausible),
                    c.notes.join("; "),
                ]
            })
        })
        .collect();
    page.table(
        &[
            "effect",
            "z",
            "parameter",
            "value ± σ",
            "unit",
            "identifiable",
            "plausible",
            "notes",
        ],
        &rows,
    );
}

/// The local anomalies of the residual (clusters no effect explains).
fn anomalies_section(page: &mut HtmlPage, report: &DiagnoseReport) {
    if report.local_anomalies.is_empty() {
        return;
    }
    page.heading("Local anomalies (no catalogue effect explains them)");
    let rows: Vec<Vec<String>> = report
        .local_anomalies
        .iter()
        .map(|a| {
            vec![
                format!(
                    "({:.1}, {:.1}, {:.1}) within {:.0} mm",
                    a.centre[0], a.centre[1], a.centre[2], a.radius_mm
                ),
                a.points.to_string(),
                a.ids.join(", "),
                a.lines
                    .iter()
                    .map(|l| l.to_string())
                    .collect::<Vec<_>>()
                    .join(", "),
                format!("{:+.2}", a.peak_um),
                format!("{:+.2}", a.mean_um),
                format!("{:.0}", a.sigma),
            ]
        })
        .collect();
    page.table(
        &[
            "where (part, mm)",
            "points",
            "plan ids",
            "program lines",
            "peak µm",
            "mean µm",
            "σ",
        ],
        &rows,
    );
}

/// One fitted parameter of an effect, with its unit and ± where known.
fn parameter_text(kind: Option<EffectKind>, name: &str, value: f64, std: Option<&f64>) -> String {
    let unit = kind.map_or("", |kind| unit_of(kind, name));
    match std {
        Some(s) if unit == "s²" => format!("{name} = {value:.3e} ± {s:.1e} {unit}"),
        Some(s) => format!("{name} = {value:.3} ± {s:.3} {unit}"),
        None => format!("{name} = {value:.3} {unit}"),
    }
}

/// Every effect of the catalogue, best first, with its held-out scores.
fn effects_section(page: &mut HtmlPage, report: &DiagnoseReport) {
    page.heading("Effects (best first, cross-validated by region and by time)");
    let rows: Vec<Vec<String>> = report
        .effects
        .iter()
        .map(|e| {
            let kind = EffectKind::from_name(&e.name);
            let params: Vec<String> = e
                .params
                .iter()
                .map(|(k, v)| parameter_text(kind, k, *v, e.params_std.get(k)))
                .collect();
            vec![
                e.name.clone(),
                if report.selected.contains(&e.name) {
                    "yes".into()
                } else {
                    String::new()
                },
                params.join(", "),
                format!("{:.3}", e.heldout_rms_before_um),
                format!("{:.3}", e.heldout_rms_after_um),
                format!("{:.1}", e.shrink_pct),
                format!("{:.1}", e.bic),
                e.aliases.join(", "),
            ]
        })
        .collect();
    page.table(
        &[
            "effect",
            "selected",
            "parameters",
            "held-out RMS before µm",
            "after µm",
            "shrink %",
            "BIC",
            "aliases",
        ],
        &rows,
    );
}

/// The residual over the part (before and after, one colour scale) and
/// against time, A and C.
fn residual_plots_section(page: &mut HtmlPage, report: &DiagnoseReport) {
    let lim = report
        .residuals
        .iter()
        .map(|p| p.residual_um.abs())
        .fold(1e-3f64, f64::max);
    page.heading("Where the gap lies");
    page.figure(
        &residual_map(report, false, lim),
        "Residual over the part (same colour scale before and after).",
    );
    page.figure(
        &residual_map(report, true, lim),
        "Residual after adding the selected effects.",
    );
    page.figure(
        &scatter(
            report,
            |p| p.time_min,
            "Residual vs machining time",
            "time (min)",
        ),
        "Red: before, blue: after.",
    );
    // The machine's own rotary axes (A and C, B and C, …).
    let axis = |k: usize| {
        report
            .rotary_axes
            .get(k)
            .map_or(["A", "C"][k], |s| s.as_str())
    };
    for (k, value) in [|p: &PointResidual| p.a_deg, |p: &PointResidual| p.c_deg]
        .into_iter()
        .enumerate()
    {
        page.figure(
            &scatter(
                report,
                value,
                &format!("Residual vs {}", axis(k)),
                &format!("{} (deg)", axis(k)),
            ),
            "",
        );
    }
}

/// The residual by region, by time band, by axis direction, and the worst points.
fn localisation_section(page: &mut HtmlPage, report: &DiagnoseReport) {
    let l = &report.localization;
    page.heading("Localisation");
    page.table(
        &["region", "points", "RMS µm", "mean µm"],
        &l.by_region
            .iter()
            .map(|r| {
                vec![
                    r.name.clone(),
                    r.points.to_string(),
                    format!("{:.3}", r.rms_um),
                    format!("{:.3}", r.mean_um),
                ]
            })
            .collect::<Vec<_>>(),
    );
    page.table(
        &["time from min", "to min", "points", "RMS µm", "mean µm"],
        &l.by_time
            .iter()
            .map(|b| {
                vec![
                    format!("{:.2}", b.from_min),
                    format!("{:.2}", b.to_min),
                    b.points.to_string(),
                    format!("{:.3}", b.rms_um),
                    format!("{:.3}", b.mean_um),
                ]
            })
            .collect::<Vec<_>>(),
    );
    page.table(
        &["axis", "direction", "points", "RMS µm", "mean µm"],
        &l.by_direction
            .iter()
            .map(|d| {
                vec![
                    d.axis.clone(),
                    d.sign.clone(),
                    d.points.to_string(),
                    format!("{:.3}", d.rms_um),
                    format!("{:.3}", d.mean_um),
                ]
            })
            .collect::<Vec<_>>(),
    );
    page.table(
        &["worst point", "residual µm", "line", "time min"],
        &l.worst_points_detail
            .iter()
            .map(|w| {
                vec![
                    w.id.clone(),
                    format!("{:.3}", w.residual_um),
                    w.line.to_string(),
                    format!("{:.2}", w.time_min),
                ]
            })
            .collect::<Vec<_>>(),
    );
}

/// The header of a table of separations between a selected effect and a rival.
const SEPARATION_HEADER: [&str; 6] = [
    "selected",
    "rival",
    "before σ",
    "expected σ if selected",
    "expected σ if rival",
    "achieved σ",
];

/// The rows of a table of separations.
fn separation_rows(list: &[Separation]) -> Vec<Vec<String>> {
    list.iter()
        .map(|s| {
            vec![
                s.selected.clone(),
                s.rival.clone(),
                format!("{:.1}", s.before_sigma),
                format!("{:.1}", s.if_selected_sigma),
                format!("{:.1}", s.if_rival_sigma),
                s.achieved_sigma.map_or("—".into(), |a| format!("{a:+.1}")),
            ]
        })
        .collect()
}

/// The follow-up's design (its probes) and its outcome, where the report has them.
fn followup_sections(page: &mut HtmlPage, report: &DiagnoseReport) {
    if let Some(design) = &report.followup_design {
        page.heading("Follow-up design");
        for line in &design.explanation {
            page.paragraph(line);
        }
        page.table(&SEPARATION_HEADER, &separation_rows(&design.separations));
        let letter = |k: usize| {
            report
                .rotary_axes
                .get(k)
                .map_or(["A", "C"][k], |s| s.as_str())
        };
        let (first, second) = (format!("{} °", letter(0)), format!("{} °", letter(1)));
        page.table(
            &["probe", "plan point", "pose", &first, &second, "t min"],
            &design
                .probes
                .iter()
                .map(|p| {
                    vec![
                        p.id.clone(),
                        p.point_id.clone(),
                        p.pose.clone(),
                        format!("{:.4}", p.a_deg),
                        format!("{:.4}", p.c_deg),
                        format!("{:.2}", p.time_min),
                    ]
                })
                .collect::<Vec<_>>(),
        );
    }
    if let Some(outcome) = &report.followup {
        page.heading("Follow-up");
        page.paragraph(&format!(
            "{} probes, readings {:.2} µm RMS beyond the model; selected before: {}.",
            outcome.probes,
            outcome.reading_rms_um,
            if outcome.selected_before.is_empty() {
                "none".to_string()
            } else {
                outcome.selected_before.join(" + ")
            }
        ));
        page.table(&SEPARATION_HEADER, &separation_rows(&outcome.separations));
    }
}
