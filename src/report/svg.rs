//! A small, dependency-free SVG chart kit: the pictures of `fit --plot`, `map`,
//! `predict --html` and `diagnose --html`.
//!
//! Invariants: pure string building, no I/O; every number written is finite
//! (non-finite data points are skipped, never printed as `NaN`).
use std::fmt::Write as _;

/// An SVG document under construction.
#[derive(Clone, Debug)]
pub struct Svg {
    width: f64,
    height: f64,
    body: String,
}

fn esc(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn ok(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

impl Svg {
    pub fn new(width: f64, height: f64) -> Self {
        Svg {
            width,
            height,
            body: String::new(),
        }
    }

    pub fn width(&self) -> f64 {
        self.width
    }

    pub fn rect(&mut self, x: f64, y: f64, w: f64, h: f64, fill: &str, stroke: Option<&str>) {
        if !ok(&[x, y, w, h]) {
            return;
        }
        let stroke = stroke.map_or(String::new(), |s| format!(r#" stroke="{s}""#));
        let _ = writeln!(
            self.body,
            r#"<rect x="{x:.2}" y="{y:.2}" width="{w:.2}" height="{h:.2}" fill="{fill}"{stroke} shape-rendering="crispEdges"/>"#
        );
    }

    pub fn line(&mut self, x1: f64, y1: f64, x2: f64, y2: f64, stroke: &str, width: f64) {
        if !ok(&[x1, y1, x2, y2]) {
            return;
        }
        let _ = writeln!(
            self.body,
            r#"<line x1="{x1:.2}" y1="{y1:.2}" x2="{x2:.2}" y2="{y2:.2}" stroke="{stroke}" stroke-width="{width}"/>"#
        );
    }

    pub fn dashed_line(&mut self, x1: f64, y1: f64, x2: f64, y2: f64, stroke: &str) {
        if !ok(&[x1, y1, x2, y2]) {
            return;
        }
        let _ = writeln!(
            self.body,
            r#"<line x1="{x1:.2}" y1="{y1:.2}" x2="{x2:.2}" y2="{y2:.2}" stroke="{stroke}" stroke-width="1" stroke-dasharray="4 3"/>"#
        );
    }

    pub fn polyline(&mut self, points: &[(f64, f64)], stroke: &str, width: f64) {
        let mut d = String::new();
        for &(x, y) in points
            .iter()
            .filter(|(x, y)| x.is_finite() && y.is_finite())
        {
            let _ = write!(d, "{x:.2},{y:.2} ");
        }
        if d.is_empty() {
            return;
        }
        let _ = writeln!(
            self.body,
            r#"<polyline points="{}" fill="none" stroke="{stroke}" stroke-width="{width}"/>"#,
            d.trim_end()
        );
    }

    pub fn circle(&mut self, x: f64, y: f64, r: f64, fill: &str, title: Option<&str>) {
        if !ok(&[x, y, r]) {
            return;
        }
        match title {
            Some(t) => {
                let _ = writeln!(
                    self.body,
                    r#"<circle cx="{x:.2}" cy="{y:.2}" r="{r:.2}" fill="{fill}"><title>{}</title></circle>"#,
                    esc(t)
                );
            }
            None => {
                let _ = writeln!(
                    self.body,
                    r#"<circle cx="{x:.2}" cy="{y:.2}" r="{r:.2}" fill="{fill}"/>"#
                );
            }
        }
    }

    /// An arrow from (x1, y1) to (x2, y2) with a small head.
    pub fn arrow(&mut self, x1: f64, y1: f64, x2: f64, y2: f64, stroke: &str) {
        if !ok(&[x1, y1, x2, y2]) {
            return;
        }
        self.line(x1, y1, x2, y2, stroke, 1.0);
        let (dx, dy) = (x2 - x1, y2 - y1);
        let len = (dx * dx + dy * dy).sqrt();
        if len < 1e-9 {
            return;
        }
        let head = (len * 0.3).min(5.0);
        let (ux, uy) = (dx / len, dy / len);
        let (px, py) = (-uy, ux);
        let a = (
            x2 - ux * head + px * head * 0.5,
            y2 - uy * head + py * head * 0.5,
        );
        let b = (
            x2 - ux * head - px * head * 0.5,
            y2 - uy * head - py * head * 0.5,
        );
        let _ = writeln!(
            self.body,
            r#"<polygon points="{x2:.2},{y2:.2} {:.2},{:.2} {:.2},{:.2}" fill="{stroke}"/>"#,
            a.0, a.1, b.0, b.1
        );
    }

    pub fn text(&mut self, x: f64, y: f64, size: f64, anchor: &str, text: &str) {
        if !ok(&[x, y]) {
            return;
        }
        let _ = writeln!(
            self.body,
            r#"<text x="{x:.2}" y="{y:.2}" font-size="{size}" text-anchor="{anchor}" font-family="sans-serif">{}</text>"#,
            esc(text)
        );
    }

    pub fn rotated_text(&mut self, x: f64, y: f64, size: f64, text: &str) {
        if !ok(&[x, y]) {
            return;
        }
        let _ = writeln!(
            self.body,
            r#"<text x="{x:.2}" y="{y:.2}" font-size="{size}" text-anchor="middle" font-family="sans-serif" transform="rotate(-90 {x:.2} {y:.2})">{}</text>"#,
            esc(text)
        );
    }

    /// The finished document.
    pub fn finish(&self) -> String {
        format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n{}</svg>\n",
            self.body,
            w = self.width,
            h = self.height
        )
    }
}

/// A linear map from a data interval to a pixel interval.
#[derive(Clone, Copy, Debug)]
pub struct Scale {
    pub d0: f64,
    pub d1: f64,
    pub p0: f64,
    pub p1: f64,
}

impl Scale {
    pub fn new(d0: f64, d1: f64, p0: f64, p1: f64) -> Self {
        let (d0, d1) = if (d1 - d0).abs() < 1e-12 || !d0.is_finite() || !d1.is_finite() {
            let m = if d0.is_finite() { d0 } else { 0.0 };
            (m - 1.0, m + 1.0)
        } else {
            (d0, d1)
        };
        Scale { d0, d1, p0, p1 }
    }

    pub fn map(&self, v: f64) -> f64 {
        self.p0 + (v - self.d0) / (self.d1 - self.d0) * (self.p1 - self.p0)
    }

    /// Pixels per data unit (absolute).
    pub fn pixels_per_unit(&self) -> f64 {
        ((self.p1 - self.p0) / (self.d1 - self.d0)).abs()
    }
}

/// "Nice" tick positions covering [lo, hi].
pub fn ticks(lo: f64, hi: f64, approx: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
        return vec![lo];
    }
    let raw = (hi - lo) / approx.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let mut t = (lo / step).ceil() * step;
    let mut out = Vec::new();
    while t <= hi + step * 1e-9 && out.len() < 100 {
        out.push(if t.abs() < step * 1e-9 { 0.0 } else { t });
        t += step;
    }
    out
}

/// Data extent of finite values, padded by `pad` (fraction of the span).
pub fn extent(values: impl IntoIterator<Item = f64>, pad: f64) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.into_iter().filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let span = (hi - lo).max(1e-9);
    (lo - span * pad, hi + span * pad)
}

/// A chart: an SVG with a plot area, x/y scales, axes, labels and title.
#[derive(Clone, Debug)]
pub struct Chart {
    pub svg: Svg,
    pub x: Scale,
    pub y: Scale,
}

/// Layout and labels of a [`Chart`].
#[derive(Clone, Debug)]
pub struct ChartSpec<'a> {
    pub width: f64,
    pub height: f64,
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub x_range: (f64, f64),
    pub y_range: (f64, f64),
    /// Same pixels per unit on both axes (maps of a part).
    pub equal_aspect: bool,
}

impl Chart {
    pub const MARGIN_LEFT: f64 = 64.0;
    pub const MARGIN_RIGHT: f64 = 90.0;
    pub const MARGIN_TOP: f64 = 36.0;
    pub const MARGIN_BOTTOM: f64 = 48.0;

    pub fn new(spec: &ChartSpec<'_>) -> Chart {
        let mut svg = Svg::new(spec.width, spec.height);
        let (mut px0, mut px1) = (Self::MARGIN_LEFT, spec.width - Self::MARGIN_RIGHT);
        let (mut py0, mut py1) = (spec.height - Self::MARGIN_BOTTOM, Self::MARGIN_TOP);
        let (xr, yr) = (spec.x_range, spec.y_range);
        if spec.equal_aspect {
            let sx = (px1 - px0) / (xr.1 - xr.0).max(1e-9);
            let sy = (py0 - py1) / (yr.1 - yr.0).max(1e-9);
            let s = sx.min(sy);
            let (wx, wy) = ((xr.1 - xr.0) * s, (yr.1 - yr.0) * s);
            let cx = 0.5 * (px0 + px1);
            let cy = 0.5 * (py0 + py1);
            px0 = cx - wx / 2.0;
            px1 = cx + wx / 2.0;
            py0 = cy + wy / 2.0;
            py1 = cy - wy / 2.0;
        }
        let x = Scale::new(xr.0, xr.1, px0, px1);
        let y = Scale::new(yr.0, yr.1, py0, py1);
        svg.rect(px0, py1, px1 - px0, py0 - py1, "#fafafa", Some("#999"));
        for t in ticks(x.d0, x.d1, 6) {
            let px = x.map(t);
            svg.line(px, py0, px, py0 + 4.0, "#333", 1.0);
            svg.text(px, py0 + 16.0, 11.0, "middle", &format_tick(t));
        }
        for t in ticks(y.d0, y.d1, 5) {
            let py = y.map(t);
            svg.line(px0 - 4.0, py, px0, py, "#333", 1.0);
            svg.line(px0, py, px1, py, "#e4e4e4", 0.5);
            svg.text(px0 - 6.0, py + 4.0, 11.0, "end", &format_tick(t));
        }
        svg.text(
            0.5 * (px0 + px1),
            spec.height - 10.0,
            12.0,
            "middle",
            spec.x_label,
        );
        svg.rotated_text(16.0, 0.5 * (py0 + py1), 12.0, spec.y_label);
        svg.text(spec.width / 2.0, 22.0, 14.0, "middle", spec.title);
        Chart { svg, x, y }
    }

    pub fn point(&mut self, x: f64, y: f64, r: f64, fill: &str, title: Option<&str>) {
        let (px, py) = (self.x.map(x), self.y.map(y));
        self.svg.circle(px, py, r, fill, title);
    }

    pub fn polyline(&mut self, points: &[(f64, f64)], stroke: &str, width: f64) {
        let mapped: Vec<(f64, f64)> = points
            .iter()
            .map(|&(x, y)| (self.x.map(x), self.y.map(y)))
            .collect();
        self.svg.polyline(&mapped, stroke, width);
    }

    pub fn vertical_marker(&mut self, x: f64, stroke: &str) {
        let px = self.x.map(x);
        self.svg.dashed_line(px, self.y.p0, px, self.y.p1, stroke);
    }

    /// An arrow starting at data point (x, y), with a pixel offset (dx, dy) in data
    /// orientation (positive dy points up).
    pub fn arrow_pixels(&mut self, x: f64, y: f64, dx: f64, dy: f64, stroke: &str) {
        let (px, py) = (self.x.map(x), self.y.map(y));
        self.svg.arrow(px, py, px + dx, py - dy, stroke);
    }

    /// A colour bar on the right margin for values in [lo, hi].
    pub fn colour_bar(&mut self, lo: f64, hi: f64, map: ColourMap, label: &str) {
        let x0 = self.svg.width() - Self::MARGIN_RIGHT + 18.0;
        let (top, bottom) = (self.y.p1, self.y.p0);
        let n = 40;
        let h = (bottom - top) / n as f64;
        for i in 0..n {
            let t = (i as f64 + 0.5) / n as f64;
            let v = lo + (hi - lo) * t;
            let y = bottom - (i as f64 + 1.0) * h;
            self.svg
                .rect(x0, y, 14.0, h + 0.5, &map.colour(v, lo, hi), None);
        }
        self.svg
            .text(x0 + 18.0, bottom, 10.0, "start", &format_tick(lo));
        self.svg
            .text(x0 + 18.0, top + 8.0, 10.0, "start", &format_tick(hi));
        self.svg.text(x0 + 7.0, top - 6.0, 10.0, "middle", label);
    }

    pub fn legend(&mut self, entries: &[(&str, &str)]) {
        let x = self.x.p0 + 8.0;
        let mut y = self.y.p1 + 14.0;
        for (colour, name) in entries {
            self.svg.rect(x, y - 8.0, 10.0, 10.0, colour, None);
            self.svg.text(x + 14.0, y, 11.0, "start", name);
            y += 14.0;
        }
    }

    pub fn finish(&self) -> String {
        self.svg.finish()
    }
}

fn format_tick(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if (0.01..100000.0).contains(&a) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.2e}")
    }
}

/// Colour maps: sequential for magnitudes, diverging (blue–white–red) for signed values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColourMap {
    Sequential,
    Diverging,
}

impl ColourMap {
    /// CSS colour of `v` on [lo, hi] (diverging maps are centred on 0).
    pub fn colour(self, v: f64, lo: f64, hi: f64) -> String {
        let (r, g, b) = match self {
            ColourMap::Sequential => {
                let t = if hi > lo {
                    ((v - lo) / (hi - lo)).clamp(0.0, 1.0)
                } else {
                    0.5
                };
                // A perceptually ordered ramp (dark blue → teal → yellow).
                let stops = [
                    (0.0, (68.0, 1.0, 84.0)),
                    (0.25, (59.0, 82.0, 139.0)),
                    (0.5, (33.0, 145.0, 140.0)),
                    (0.75, (94.0, 201.0, 98.0)),
                    (1.0, (253.0, 231.0, 37.0)),
                ];
                interpolate_stops(&stops, t)
            }
            ColourMap::Diverging => {
                let m = lo.abs().max(hi.abs()).max(1e-12);
                let t = (v / m).clamp(-1.0, 1.0);
                if t < 0.0 {
                    let s = -t;
                    (
                        255.0 * (1.0 - s) + 33.0 * s,
                        255.0 * (1.0 - s) + 102.0 * s,
                        255.0 * (1.0 - s) + 172.0 * s,
                    )
                } else {
                    (
                        255.0 * (1.0 - t) + 178.0 * t,
                        255.0 * (1.0 - t) + 24.0 * t,
                        255.0 * (1.0 - t) + 43.0 * t,
                    )
                }
            }
        };
        format!(
            "rgb({},{},{})",
            r.round() as u8,
            g.round() as u8,
            b.round() as u8
        )
    }
}

fn interpolate_stops(stops: &[(f64, (f64, f64, f64))], t: f64) -> (f64, f64, f64) {
    for w in stops.windows(2) {
        let (t0, c0) = w[0];
        let (t1, c1) = w[1];
        if t <= t1 {
            let s = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
            return (
                c0.0 + (c1.0 - c0.0) * s,
                c0.1 + (c1.1 - c0.1) * s,
                c0.2 + (c1.2 - c0.2) * s,
            );
        }
    }
    stops[stops.len() - 1].1
}

/// A histogram of `values` with `bins` bins.
pub fn histogram(values: &[f64], bins: usize, title: &str, x_label: &str) -> String {
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    let (lo, hi) = extent(finite.iter().copied(), 0.0);
    let bins = bins.max(1);
    let width = (hi - lo).max(1e-9) / bins as f64;
    let mut counts = vec![0usize; bins];
    for v in &finite {
        let i = (((v - lo) / width) as usize).min(bins - 1);
        counts[i] += 1;
    }
    let max = counts.iter().copied().max().unwrap_or(1).max(1) as f64;
    let mut chart = Chart::new(&ChartSpec {
        width: 520.0,
        height: 300.0,
        title,
        x_label,
        y_label: "count",
        x_range: (lo, lo + width * bins as f64),
        y_range: (0.0, max * 1.05),
        equal_aspect: false,
    });
    for (i, &c) in counts.iter().enumerate() {
        let x0 = chart.x.map(lo + width * i as f64);
        let x1 = chart.x.map(lo + width * (i + 1) as f64);
        let y0 = chart.y.map(0.0);
        let y1 = chart.y.map(c as f64);
        chart.svg.rect(
            x0 + 0.5,
            y1,
            (x1 - x0 - 1.0).max(0.5),
            y0 - y1,
            "#4a7ab5",
            None,
        );
    }
    chart.finish()
}

/// A self-contained HTML page around SVG figures and preformatted text.
#[derive(Clone, Debug, Default)]
pub struct HtmlPage {
    title: String,
    body: String,
}

impl HtmlPage {
    pub fn new(title: &str) -> Self {
        HtmlPage {
            title: title.to_string(),
            body: String::new(),
        }
    }

    pub fn heading(&mut self, text: &str) {
        let _ = writeln!(self.body, "<h2>{}</h2>", esc(text));
    }

    pub fn paragraph(&mut self, text: &str) {
        let _ = writeln!(self.body, "<p>{}</p>", esc(text));
    }

    pub fn preformatted(&mut self, text: &str) {
        let _ = writeln!(self.body, "<pre>{}</pre>", esc(text));
    }

    /// A table: header row and body rows (cells are escaped).
    pub fn table(&mut self, header: &[&str], rows: &[Vec<String>]) {
        self.body.push_str("<table><tr>");
        for h in header {
            let _ = write!(self.body, "<th>{}</th>", esc(h));
        }
        self.body.push_str("</tr>\n");
        for row in rows {
            self.body.push_str("<tr>");
            for cell in row {
                let _ = write!(self.body, "<td>{}</td>", esc(cell));
            }
            self.body.push_str("</tr>\n");
        }
        self.body.push_str("</table>\n");
    }

    /// Inline an SVG figure (as produced by this module) with a caption.
    pub fn figure(&mut self, svg: &str, caption: &str) {
        let _ = writeln!(
            self.body,
            "<figure>{svg}<figcaption>{}</figcaption></figure>",
            esc(caption)
        );
    }

    pub fn finish(&self) -> String {
        format!(
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{t}</title>\n<style>body{{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}}figure{{display:inline-block;margin:0.5em}}figcaption{{font-size:0.85em;color:#555}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 8px;text-align:right}}pre{{background:#f5f5f5;padding:0.8em}}</style></head>\n<body><h1>{t}</h1>\n{b}</body></html>\n",
            t = esc(&self.title),
            b = self.body
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_nice_and_cover() {
        assert_eq!(ticks(0.0, 10.0, 5), vec![0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        let t = ticks(-3.3, 7.1, 5);
        assert!(t.first().unwrap() >= &-3.3 && t.last().unwrap() <= &7.1);
    }

    #[test]
    fn non_finite_points_are_skipped() {
        let mut s = Svg::new(10.0, 10.0);
        s.circle(f64::NAN, 1.0, 1.0, "red", None);
        s.polyline(
            &[(0.0, 0.0), (f64::INFINITY, 1.0), (2.0, 2.0)],
            "black",
            1.0,
        );
        let out = s.finish();
        assert!(!out.contains("NaN") && !out.contains("inf"));
        assert!(out.contains("0.00,0.00 2.00,2.00"));
    }

    #[test]
    fn diverging_map_is_white_at_zero() {
        assert_eq!(
            ColourMap::Diverging.colour(0.0, -1.0, 1.0),
            "rgb(255,255,255)"
        );
    }

    #[test]
    fn text_is_escaped() {
        let mut p = HtmlPage::new("a<b");
        p.paragraph("x & y");
        let html = p.finish();
        assert!(html.contains("a&lt;b") && html.contains("x &amp; y"));
    }
}
