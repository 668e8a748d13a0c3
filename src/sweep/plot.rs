//! The work-precision diagram of a sweep as SVG: error against wall time, both axes
//! logarithmic, one series per integrator.
//!
//! Each point is a succeeded run; its error is the error against the reference when there is
//! one, else the run's own estimate. Points of a series are joined in order of wall time.

use std::fmt::Write as _;
use std::io::{self, Write};

use super::table::Table;

const WIDTH: f64 = 640.0;
const HEIGHT: f64 = 440.0;
const MARGIN_LEFT: f64 = 80.0;
const MARGIN_RIGHT: f64 = 150.0;
const MARGIN_TOP: f64 = 30.0;
const MARGIN_BOTTOM: f64 = 60.0;
const COLOURS: [&str; 6] = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"];

/// Writes the diagram.
pub fn write_svg<W: Write>(table: &Table, title: &str, mut out: W) -> io::Result<()> {
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for row in table.rows.iter().filter(|r| r.status == "succeeded") {
        let Some(error) = row.error() else { continue };
        if row.wall_time_s <= 0.0 || !row.wall_time_s.is_finite() {
            continue;
        }
        let point = (row.wall_time_s, error);
        match series.iter_mut().find(|(name, _)| *name == row.integrator) {
            Some((_, points)) => points.push(point),
            None => series.push((row.integrator.clone(), vec![point])),
        }
    }
    for (_, points) in &mut series {
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    let all: Vec<(f64, f64)> = series.iter().flat_map(|(_, p)| p.iter().copied()).collect();
    let (x_range, y_range) = (decades(all.iter().map(|p| p.0)), decades(all.iter().map(|p| p.1)));
    let plot_w = WIDTH - MARGIN_LEFT - MARGIN_RIGHT;
    let plot_h = HEIGHT - MARGIN_TOP - MARGIN_BOTTOM;
    let sx = |x: f64| MARGIN_LEFT + (x.log10() - x_range.0) / (x_range.1 - x_range.0) * plot_w;
    let sy = |y: f64| MARGIN_TOP + plot_h - (y.log10() - y_range.0) / (y_range.1 - y_range.0) * plot_h;

    let mut svg = String::new();
    let _ = writeln!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" viewBox="0 0 {WIDTH} {HEIGHT}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(svg, r#"<title>{}</title>"#, escape(title));
    let _ = writeln!(svg, r#"<rect width="{WIDTH}" height="{HEIGHT}" fill="white"/>"#);
    let _ = writeln!(
        svg,
        r#"<g class="axes" stroke="black" fill="none"><rect x="{MARGIN_LEFT}" y="{MARGIN_TOP}" width="{plot_w}" height="{plot_h}"/></g>"#
    );
    let _ = writeln!(svg, r#"<g class="x-axis" text-anchor="middle">"#);
    for decade in x_range.0 as i32..=x_range.1 as i32 {
        let x = sx(10f64.powi(decade));
        let bottom = MARGIN_TOP + plot_h;
        let _ = writeln!(
            svg,
            r#"<line x1="{x:.1}" y1="{bottom}" x2="{x:.1}" y2="{:.1}" stroke="black"/>"#,
            bottom + 5.0
        );
        let _ = writeln!(svg, r#"<text x="{x:.1}" y="{:.1}">1e{decade}</text>"#, bottom + 20.0);
    }
    let _ = writeln!(
        svg,
        r#"<text class="label" x="{:.1}" y="{:.1}">wall time (s, log scale)</text></g>"#,
        MARGIN_LEFT + plot_w / 2.0,
        HEIGHT - 15.0
    );
    let _ = writeln!(svg, r#"<g class="y-axis" text-anchor="end">"#);
    for decade in y_range.0 as i32..=y_range.1 as i32 {
        let y = sy(10f64.powi(decade));
        let _ = writeln!(
            svg,
            r#"<line x1="{:.1}" y1="{y:.1}" x2="{MARGIN_LEFT}" y2="{y:.1}" stroke="black"/>"#,
            MARGIN_LEFT - 5.0
        );
        let _ = writeln!(svg, r#"<text x="{:.1}" y="{:.1}">1e{decade}</text>"#, MARGIN_LEFT - 8.0, y + 4.0);
    }
    let _ = writeln!(
        svg,
        r#"<text class="label" transform="translate(18 {:.1}) rotate(-90)" text-anchor="middle">error (m, log scale)</text></g>"#,
        MARGIN_TOP + plot_h / 2.0
    );
    for (index, (name, points)) in series.iter().enumerate() {
        let colour = COLOURS[index % COLOURS.len()];
        let path: Vec<String> = points.iter().map(|&(x, y)| format!("{:.1},{:.1}", sx(x), sy(y))).collect();
        let _ = writeln!(
            svg,
            r#"<g class="series" data-integrator="{}" stroke="{colour}" fill="{colour}">"#,
            escape(name)
        );
        let _ = writeln!(svg, r#"<polyline points="{}" fill="none" stroke-width="1.5"/>"#, path.join(" "));
        for &(x, y) in points {
            let _ = writeln!(svg, r#"<circle cx="{:.1}" cy="{:.1}" r="3"/>"#, sx(x), sy(y));
        }
        let ly = MARGIN_TOP + 15.0 + 18.0 * index as f64;
        let lx = WIDTH - MARGIN_RIGHT + 15.0;
        let _ = writeln!(
            svg,
            r#"<line x1="{lx}" y1="{ly}" x2="{:.1}" y2="{ly}" stroke-width="2"/><text x="{:.1}" y="{:.1}" stroke="none" fill="black">{}</text></g>"#,
            lx + 20.0,
            lx + 26.0,
            ly + 4.0,
            escape(name)
        );
    }
    svg.push_str("</svg>\n");
    out.write_all(svg.as_bytes())
}

/// The whole decades that cover the values: (floor log10 of the least, ceil of the greatest),
/// at least one decade wide.
fn decades(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let (lo, hi) = (lo.log10().floor(), hi.log10().ceil());
    if hi > lo { (lo, hi) } else { (lo, lo + 1.0) }
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}
