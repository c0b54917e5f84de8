//! The `map` command's SVG: a volumetric error map (the seed paper's Fig. 12) as
//! a heat map of |e| with arrows of the in-plane error (in the machine frame, so
//! they lie in the plotted plane whatever A and C are). Pure string building.
use super::svg::{Chart, ChartSpec, ColourMap};
use crate::machine::error_map::{ErrorMap, Plane};

/// The SVG heat map: |e| as cells coloured by `heat(u, v)` (the fitted surface,
/// or the grid values), arrows of the in-plane error at the grid points.
pub(crate) fn error_map_svg(map: &ErrorMap, title: &str, heat: &dyn Fn(f64, f64) -> f64) -> String {
    let (ua, va, _) = map.spec.plane.axes();
    let x_label = format!("{} (mm)", ua.letter());
    let y_label = format!("{} (mm)", va.letter());
    let spec = ChartSpec {
        width: 760.0,
        height: 640.0,
        title,
        x_label: &x_label,
        y_label: &y_label,
        x_range: (map.spec.u_range[0], map.spec.u_range[1]),
        y_range: (map.spec.v_range[0], map.spec.v_range[1]),
        equal_aspect: true,
    };
    let mut chart = Chart::new(&spec);
    // Heat map cells on a finer raster than the grid (the surface is smooth).
    let cells = 60usize;
    let du = (map.spec.u_range[1] - map.spec.u_range[0]) / cells as f64;
    let dv = (map.spec.v_range[1] - map.spec.v_range[0]) / cells as f64;
    let mut values = Vec::with_capacity(cells * cells);
    for j in 0..cells {
        for i in 0..cells {
            let uc = map.spec.u_range[0] + (i as f64 + 0.5) * du;
            let vc = map.spec.v_range[0] + (j as f64 + 0.5) * dv;
            values.push((uc, vc, heat(uc, vc)));
        }
    }
    let lo = values
        .iter()
        .map(|v| v.2)
        .chain(map.magnitudes())
        .fold(f64::INFINITY, f64::min)
        .max(0.0);
    let hi = values
        .iter()
        .map(|v| v.2)
        .chain(map.magnitudes())
        .fold(0.0, f64::max);
    for (uc, vc, h) in &values {
        let x0 = chart.x.map(uc - du / 2.0);
        let x1 = chart.x.map(uc + du / 2.0);
        let y0 = chart.y.map(vc + dv / 2.0);
        let y1 = chart.y.map(vc - dv / 2.0);
        let colour = ColourMap::Sequential.colour(*h, lo, hi);
        chart
            .svg
            .rect(x0, y0, (x1 - x0) + 0.3, (y1 - y0) + 0.3, &colour, None);
    }
    // Arrows: longest in-plane error = 0.8 of a grid step.
    let (iu, iv) = (Plane::index(ua), Plane::index(va));
    let longest = map
        .points
        .iter()
        .map(|p| p.e_machine_um[iu].hypot(p.e_machine_um[iv]))
        .fold(0.0, f64::max);
    let step_px = (chart.x.pixels_per_unit() * (map.u[1] - map.u[0]))
        .min(chart.y.pixels_per_unit() * (map.v[1] - map.v[0]));
    if longest > 0.0 {
        let k = 0.8 * step_px / longest;
        for p in &map.points {
            let (pu, pv) = (p.joints.get(ua), p.joints.get(va));
            let (eu, ev) = (p.e_machine_um[iu], p.e_machine_um[iv]);
            if eu.hypot(ev) * k >= 1.0 {
                chart.arrow_pixels(pu, pv, eu * k, ev * k, "#ffffff");
            }
        }
        let note = format!(
            "arrows: in-plane error, longest {longest:.2} µm = {:.0} px",
            0.8 * step_px
        );
        chart
            .svg
            .text(chart.x.p0, spec.height - 26.0, 10.0, "start", &note);
    }
    chart.colour_bar(lo, hi, ColourMap::Sequential, "|e| um");
    chart.finish()
}
