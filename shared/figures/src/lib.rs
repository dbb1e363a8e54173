//! The study's figures, drawn from plain data into SVG and PNG files.
//!
//! * [`grouped_bars`]: panels of bars grouped by scene, one bar per method, with optional
//!   interval whiskers (the paper's Fig. 3).
//! * [`time_panels`]: stacked panels of time series with horizontal reference lines (limits,
//!   margins) — Fig. 4 and the clearance plot.
//! * [`path_projections`]: desired and real paths in three orthogonal projections with other
//!   tracks in grey (Fig. 2).
//!
//! Every figure is written twice, `STEM.svg` and `STEM.png`. Text uses DejaVu Sans, embedded
//! in the binary (the `dejavu` crate) and registered with plotters' `ab_glyph` renderer, so a
//! fresh machine needs no system font or font library.

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;

/// Colours of series `i` (methods, joints): a colour-blind-safe palette (Okabe–Ito).
pub const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(230, 159, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(86, 180, 233),
    RGBColor(213, 94, 0),
    RGBColor(240, 228, 66),
    RGBColor(0, 0, 0),
];

const FONT: &str = "sans-serif";

fn fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular());
        let _ = plotters::style::register_font(FONT, FontStyle::Bold, dejavu::sans::bold());
    });
}

/// A legend entry: a short line in `style`.
fn line_key(style: ShapeStyle) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], style)
}

/// The series legend, boxed, in the upper right corner.
fn legend<'a, DB: DrawingBackend + 'a>(
    chart: &mut ChartContext<
        'a,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
) -> Result<(), String> {
    boxed_legend(chart, SeriesLabelPosition::UpperRight)
}

/// The series legend, boxed, at `pos`.
fn boxed_legend<'a, DB: DrawingBackend + 'a, X: Ranged, Y: Ranged>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    pos: SeriesLabelPosition,
) -> Result<(), String> {
    chart
        .configure_series_labels()
        .position(pos)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((FONT, 12))
        .draw()
        .map_err(err)
}

fn err(e: impl std::fmt::Display) -> String {
    e.to_string()
}

/// Renders `$body` (with the drawing area bound to `$root`) into `stem.svg` and `stem.png`
/// (`w × h` pixels); evaluates to both paths.
macro_rules! both {
    ($stem:expr, $size:expr, |$root:ident| $body:expr) => {{
        fonts();
        let svg = $stem.with_extension("svg");
        let png = $stem.with_extension("png");
        {
            let $root = SVGBackend::new(&svg, $size).into_drawing_area();
            $root.fill(&WHITE).map_err(err)?;
            $body?;
            $root.present().map_err(|e| format!("{}: {e}", svg.display()))?;
        }
        {
            let $root = BitMapBackend::new(&png, $size).into_drawing_area();
            $root.fill(&WHITE).map_err(err)?;
            $body?;
            $root.present().map_err(|e| format!("{}: {e}", png.display()))?;
        }
        Ok([svg, png])
    }};
}

/// One bar: `value` of series `series` in group `group`, with an optional interval.
#[derive(Debug, Clone, PartialEq)]
pub struct Bar {
    pub group: String,
    pub series: String,
    pub value: f64,
    pub interval: Option<(f64, f64)>,
}

/// A panel of grouped bars.
#[derive(Debug, Clone, PartialEq)]
pub struct BarPanel {
    pub title: String,
    pub y_label: String,
    pub bars: Vec<Bar>,
    /// Fixed y range (e.g. `0..1` for a rate), else from the data.
    pub y_range: Option<(f64, f64)>,
}

fn uniq(v: impl Iterator<Item = String>) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for s in v {
        if !out.contains(&s) {
            out.push(s);
        }
    }
    out
}

/// Panels of bars grouped by `group` (x), one bar per `series` (colour, legend), stacked
/// vertically, with interval whiskers where given.
pub fn grouped_bars(stem: &Path, title: &str, panels: &[BarPanel]) -> Result<[PathBuf; 2], String> {
    let size = (1100, 60 + 300 * panels.len() as u32);
    both!(stem, size, |root| bars_on(&root, title, panels))
}

fn bars_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    panels: &[BarPanel],
) -> Result<(), String> {
    let root = root.titled(title, (FONT, 24).into_font().style(FontStyle::Bold)).map_err(err)?;
    let areas = root.split_evenly((panels.len().max(1), 1));
    for (panel, whole) in panels.iter().zip(areas.iter()) {
        // The legend in its own strip on the right: it never hides a bar.
        let (area, legend) = whole.split_horizontally(whole.dim_in_pixel().0.saturating_sub(150));
        let groups = uniq(panel.bars.iter().map(|b| b.group.clone()));
        let series = uniq(panel.bars.iter().map(|b| b.series.clone()));
        let ng = groups.len().max(1);
        let ns = series.len().max(1);
        let top = panel
            .bars
            .iter()
            .map(|b| b.interval.map_or(b.value, |i| i.1.max(b.value)))
            .fold(0.0f64, f64::max);
        let (y0, y1) = panel.y_range.unwrap_or((0.0, if top > 0.0 { top * 1.15 } else { 1.0 }));
        let mut chart = ChartBuilder::on(&area)
            .caption(&panel.title, (FONT, 18))
            .margin(8)
            .x_label_area_size(28)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..ng as f64, y0..y1)
            .map_err(err)?;
        let g = groups.clone();
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(ng * 2 + 1)
            .x_label_formatter(&move |x| {
                let i = x.floor() as usize;
                if (x - i as f64 - 0.5).abs() < 0.26 {
                    g.get(i).cloned().unwrap_or_default()
                } else {
                    String::new()
                }
            })
            .y_desc(&panel.y_label)
            .label_style((FONT, 13))
            .draw()
            .map_err(err)?;
        let w = 0.8 / ns as f64;
        for (si, s) in series.iter().enumerate() {
            let c = PALETTE[si % PALETTE.len()];
            let bars: Vec<(f64, &Bar)> = panel
                .bars
                .iter()
                .filter(|b| &b.series == s)
                .filter_map(|b| {
                    groups.iter().position(|g| g == &b.group).map(|gi| (gi as f64 + 0.1 + w * si as f64, b))
                })
                .collect();
            chart
                .draw_series(bars.iter().map(|(x, b)| {
                    Rectangle::new([(*x, y0), (*x + w * 0.9, b.value.clamp(y0, y1))], c.filled())
                }))
                .map_err(err)?;
            let y = 40 + 20 * si as i32;
            legend.draw(&Rectangle::new([(8, y - 6), (20, y + 6)], c.filled())).map_err(err)?;
            legend.draw(&Text::new(s.clone(), (26, y - 7), (FONT, 13))).map_err(err)?;
            chart
                .draw_series(bars.iter().filter_map(|(x, b)| {
                    b.interval.map(|(lo, hi)| {
                        let xm = *x + w * 0.45;
                        PathElement::new(
                            vec![(xm, lo.clamp(y0, y1)), (xm, hi.clamp(y0, y1))],
                            BLACK.stroke_width(2),
                        )
                    })
                }))
                .map_err(err)?;
        }
    }
    Ok(())
}

/// A time series.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    /// Palette index.
    pub color: usize,
    pub dashed: bool,
}

/// A horizontal reference line (a limit, a margin).
#[derive(Debug, Clone, PartialEq)]
pub struct HLine {
    pub y: f64,
    pub name: String,
}

/// A panel of time series.
#[derive(Debug, Clone, PartialEq)]
pub struct TimePanel {
    pub title: String,
    pub y_label: String,
    pub series: Vec<Series>,
    /// Drawn in red, dashed.
    pub lines: Vec<HLine>,
}

/// Panels of time series stacked vertically, sharing the x axis (time, s).
pub fn time_panels(stem: &Path, title: &str, panels: &[TimePanel]) -> Result<[PathBuf; 2], String> {
    let size = (1100, 60 + 260 * panels.len() as u32);
    both!(stem, size, |root| time_on(&root, title, panels))
}

fn dashed(points: &[(f64, f64)], x_span: f64) -> Vec<Vec<(f64, f64)>> {
    // Segments of ~1/150 of the span, every other one drawn.
    let seg = x_span / 150.0;
    let mut out = Vec::new();
    let mut cur = Vec::new();
    for &(x, y) in points {
        let on = ((x / seg).floor() as i64) % 2 == 0;
        if on {
            cur.push((x, y));
        } else if !cur.is_empty() {
            out.push(std::mem::take(&mut cur));
        }
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
}

fn time_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    panels: &[TimePanel],
) -> Result<(), String> {
    let root = root.titled(title, (FONT, 24).into_font().style(FontStyle::Bold)).map_err(err)?;
    let areas = root.split_evenly((panels.len().max(1), 1));
    let (mut x0, mut x1) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in panels {
        for s in &p.series {
            for &(x, _) in &s.points {
                x0 = x0.min(x);
                x1 = x1.max(x);
            }
        }
    }
    if !(x0 < x1) {
        (x0, x1) = (0.0, 1.0);
    }
    for (panel, area) in panels.iter().zip(areas.iter()) {
        let ys = panel
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.1))
            .chain(panel.lines.iter().map(|l| l.y));
        let (mut y0, mut y1) = ys
            .filter(|y| y.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| (a.min(y), b.max(y)));
        if !(y0 < y1) {
            (y0, y1) = (y0.min(0.0) - 1.0, y1.max(0.0) + 1.0);
        }
        let pad = 0.08 * (y1 - y0);
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, (FONT, 18))
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("time [s]")
            .y_desc(&panel.y_label)
            .label_style((FONT, 13))
            .draw()
            .map_err(err)?;
        for s in &panel.series {
            let c = PALETTE[s.color % PALETTE.len()];
            let style = c.stroke_width(2);
            if s.dashed {
                for (i, seg) in dashed(&s.points, x1 - x0).into_iter().enumerate() {
                    let a = chart.draw_series(LineSeries::new(seg, style)).map_err(err)?;
                    if i == 0 {
                        a.label(s.name.clone()).legend(line_key(style));
                    }
                }
            } else {
                chart
                    .draw_series(LineSeries::new(s.points.iter().copied(), style))
                    .map_err(err)?
                    .label(s.name.clone())
                    .legend(line_key(style));
            }
        }
        let mut named = Vec::new();
        for l in &panel.lines {
            let pts: Vec<(f64, f64)> = (0..=300).map(|i| (x0 + (x1 - x0) * i as f64 / 300.0, l.y)).collect();
            for (i, seg) in dashed(&pts, x1 - x0).into_iter().enumerate() {
                let a = chart.draw_series(LineSeries::new(seg, RED.stroke_width(1))).map_err(err)?;
                if i == 0 && !named.contains(&l.name) {
                    named.push(l.name.clone());
                    a.label(l.name.clone()).legend(line_key(RED.stroke_width(1)));
                }
            }
        }
        legend(&mut chart)?;
    }
    Ok(())
}

/// Desired (red) and real (green) 3-D paths in the x–y, x–z and y–z projections, with other
/// tracks (debris) in grey.
pub fn path_projections(
    stem: &Path,
    title: &str,
    desired: &[[f64; 3]],
    real: &[[f64; 3]],
    others: &[Vec<[f64; 3]>],
) -> Result<[PathBuf; 2], String> {
    both!(stem, (1500, 560), |root| paths_on(&root, title, desired, real, others))
}

fn paths_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    desired: &[[f64; 3]],
    real: &[[f64; 3]],
    others: &[Vec<[f64; 3]>],
) -> Result<(), String> {
    let root = root.titled(title, (FONT, 24).into_font().style(FontStyle::Bold)).map_err(err)?;
    let areas = root.split_evenly((1, 3));
    let names = ["x", "y", "z"];
    for (area, (a, b)) in areas.iter().zip([(0usize, 1usize), (0, 2), (1, 2)]) {
        // A square window around the arm's paths (debris only where they pass through it).
        let all = desired.iter().chain(real.iter());
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in all {
            lo = [lo[0].min(p[a]), lo[1].min(p[b])];
            hi = [hi[0].max(p[a]), hi[1].max(p[b])];
        }
        if !(lo[0] <= hi[0]) {
            (lo, hi) = ([-1.0, -1.0], [1.0, 1.0]);
        }
        let half = 0.5 * (hi[0] - lo[0]).max(hi[1] - lo[1]).max(0.2) + 0.6;
        let c = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
        let mut chart = ChartBuilder::on(area)
            .caption(format!("{}–{} projection", names[a], names[b]), (FONT, 18))
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(50)
            .build_cartesian_2d((c[0] - half)..(c[0] + half), (c[1] - half)..(c[1] + half))
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(format!("{} [m]", names[a]))
            .y_desc(format!("{} [m]", names[b]))
            .label_style((FONT, 13))
            .draw()
            .map_err(err)?;
        let inside = |p: &[f64; 3]| (p[a] - c[0]).abs() <= half && (p[b] - c[1]).abs() <= half;
        for (i, tr) in others.iter().enumerate() {
            // Only the parts inside the window (a track leaving it is split there).
            let mut seg: Vec<(f64, f64)> = Vec::new();
            let mut first = true;
            for p in tr.iter().chain(std::iter::once(&[f64::NAN; 3])) {
                if p[0].is_finite() && inside(p) {
                    seg.push((p[a], p[b]));
                    continue;
                }
                if seg.len() > 1 {
                    let s = chart
                        .draw_series(LineSeries::new(
                            std::mem::take(&mut seg),
                            RGBColor(150, 150, 150).stroke_width(1),
                        ))
                        .map_err(err)?;
                    if i == 0 && first {
                        s.label("debris (true)").legend(line_key(RGBColor(150, 150, 150).stroke_width(1)));
                    }
                    first = false;
                }
                seg.clear();
            }
        }
        chart
            .draw_series(LineSeries::new(
                desired.iter().map(|p| (p[a], p[b])),
                RGBColor(220, 30, 30).stroke_width(3),
            ))
            .map_err(err)?
            .label("desired")
            .legend(line_key(RGBColor(220, 30, 30).stroke_width(3)));
        chart
            .draw_series(LineSeries::new(
                real.iter().map(|p| (p[a], p[b])),
                RGBColor(20, 160, 60).stroke_width(1),
            ))
            .map_err(err)?
            .label("real")
            .legend(line_key(RGBColor(20, 160, 60).stroke_width(1)));
        legend(&mut chart)?;
    }
    Ok(())
}

/// A percentile curve: `(nines, value)` points, `nines = -log10(1 - q)` (as
/// `dkrrt_rt::hist::LatencyHist::curve_us` gives them).
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    /// Palette index.
    pub color: usize,
    pub dashed: bool,
}

/// A panel of percentile curves.
#[derive(Debug, Clone, PartialEq)]
pub struct CurvePanel {
    pub title: String,
    pub y_label: String,
    pub curves: Vec<Curve>,
}

/// The x-axis label of `nines`: the percentile it stands for ("90%", "99.9%").
fn percent_label(nines: f64) -> String {
    let p = 100.0 * (1.0 - 10f64.powf(-nines));
    let decimals = (nines.round() as i64 - 2).clamp(0, 6) as usize;
    format!("{p:.decimals$}%")
}

/// HdrHistogram-style latency plots: panels side by side, each with its curves over the
/// percentile (x: 0, 90, 99, 99.9 … %, spaced by nines) on a logarithmic value axis.
pub fn percentile_curves(stem: &Path, title: &str, panels: &[CurvePanel]) -> Result<[PathBuf; 2], String> {
    let cols = panels.len().clamp(1, 2);
    let rows = panels.len().div_ceil(2).max(1);
    let size = (560 * cols as u32, 60 + 380 * rows as u32);
    both!(stem, size, |root| curves_on(&root, title, panels, rows, cols))
}

fn curves_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    panels: &[CurvePanel],
    rows: usize,
    cols: usize,
) -> Result<(), String> {
    let root = root.titled(title, (FONT, 22).into_font().style(FontStyle::Bold)).map_err(err)?;
    let areas = root.split_evenly((rows, cols));
    for (panel, area) in panels.iter().zip(areas.iter()) {
        let pts =
            || panel.curves.iter().flat_map(|c| c.points.iter()).filter(|p| p.1 > 0.0 && p.1.is_finite());
        let x1 = pts().map(|p| p.0).fold(1.0f64, f64::max).ceil();
        let y0 = pts().map(|p| p.1).fold(f64::INFINITY, f64::min);
        let y1 = pts().map(|p| p.1).fold(0.0f64, f64::max);
        let (y0, y1) = if y0 < y1 { (y0 / 1.5, y1 * 1.5) } else { (0.1, 10.0) };
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, (FONT, 16))
            .margin(10)
            .x_label_area_size(32)
            .y_label_area_size(64)
            .build_cartesian_2d(0.0..x1, (y0..y1).log_scale())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("percentile")
            .y_desc(&panel.y_label)
            .x_labels(x1 as usize + 1)
            .x_label_formatter(&|x| percent_label(*x))
            .label_style((FONT, 12))
            .draw()
            .map_err(err)?;
        for c in &panel.curves {
            let color = PALETTE[c.color % PALETTE.len()];
            let style = color.stroke_width(2);
            let points: Vec<(f64, f64)> =
                c.points.iter().copied().filter(|p| p.1 > 0.0 && p.1.is_finite()).collect();
            if c.dashed {
                for (i, seg) in dashed(&points, x1).into_iter().enumerate() {
                    let a = chart.draw_series(LineSeries::new(seg, style)).map_err(err)?;
                    if i == 0 {
                        a.label(c.name.clone()).legend(line_key(style));
                    }
                }
            } else {
                chart
                    .draw_series(LineSeries::new(points, style))
                    .map_err(err)?
                    .label(c.name.clone())
                    .legend(line_key(style));
            }
        }
        boxed_legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    }
    Ok(())
}

/// A depth camera frame as a PNG (`path`): depth (near bright, far dark, no return black; the
/// shades span the frame's own nearest to farthest return) beside the instances (one colour
/// per object, the arm white), each pixel drawn 4 times larger. `depth` and `instance` are
/// row-major `width × height`; `arm` is the arm's instance value.
#[allow(clippy::too_many_arguments)]
pub fn depth_frame_png(
    path: &Path,
    title: &str,
    width: usize,
    height: usize,
    depth: &[f32],
    instance: &[u8],
    arm: u8,
) -> Result<PathBuf, String> {
    fonts();
    let scale = 4usize;
    let (pw, ph) = ((width * scale) as u32, (height * scale) as u32);
    let (gap, top) = (20u32, 60u32);
    let root = BitMapBackend::new(path, (2 * pw + 3 * gap, ph + top + 2 * gap)).into_drawing_area();
    let e = |x: DrawingAreaErrorKind<_>| x.to_string();
    root.fill(&WHITE).map_err(e)?;
    root.titled(title, (FONT, 22)).map_err(e)?;
    let style = TextStyle::from((FONT, 16).into_font());
    let label_y = (top - 24) as i32;
    root.draw_text("depth (bright: near; black: no return)", &style, (gap as i32, label_y)).map_err(e)?;
    root.draw_text("instances (white: the arm)", &style, ((2 * gap + pw) as i32, label_y)).map_err(e)?;
    let valid = depth[..width * height].iter().filter(|&&d| d > 0.0).map(|&d| d as f64);
    let (near, far) = valid.fold((f64::INFINITY, 0.0f64), |(a, b), d| (a.min(d), b.max(d)));
    let span = (far - near).max(1e-6);
    root.draw_text(
        &format!("nearest {near:.2} m, farthest {far:.2} m"),
        &style,
        (gap as i32, (top + ph + 2) as i32),
    )
    .map_err(e)?;
    for v in 0..height {
        for u in 0..width {
            let k = v * width + u;
            let d = depth[k] as f64;
            let c = if d <= 0.0 {
                RGBColor(0, 0, 0)
            } else {
                let s = 1.0 - ((d - near) / span).clamp(0.0, 1.0);
                let g = (50.0 + 205.0 * s) as u8;
                RGBColor(g, g, (g as f64 * 0.85) as u8)
            };
            let inst = instance[k];
            let ci = if inst == 0 {
                RGBColor(20, 20, 20)
            } else if inst == arm {
                RGBColor(255, 255, 255)
            } else {
                let p = PALETTE[(inst as usize - 1) % 7];
                // Vary the shade per id beyond the palette's length.
                let f = 1.0 - 0.3 * (((inst as usize - 1) / 7) % 3) as f64;
                RGBColor((p.0 as f64 * f) as u8, (p.1 as f64 * f) as u8, (p.2 as f64 * f) as u8)
            };
            for (panel, col) in [(0u32, c), (1, ci)] {
                let x0 = (gap + panel * (pw + gap)) as i32 + (u * scale) as i32;
                let y0 = top as i32 + (v * scale) as i32;
                root.draw(&Rectangle::new([(x0, y0), (x0 + scale as i32, y0 + scale as i32)], col.filled()))
                    .map_err(e)?;
            }
        }
    }
    root.present().map_err(e)?;
    Ok(path.to_path_buf())
}
