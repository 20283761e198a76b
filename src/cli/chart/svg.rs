//! A small SVG plotter for the charts: log-log panels sharing their axes, decade ticks and
//! labels (`10ⁿ`), minor ticks, markers, polylines (solid or dashed), a legend and notes.
//! No dependencies; the output is plain SVG 1.1 text.
//!
//! Data space to the page: `X(x) = left + (log10 x − log10 x_lo) / (log10 x_hi − log10 x_lo) · width`
//! (and likewise `Y`, upwards), with `[x_lo, x_hi]` the whole decades around every point of
//! the series that set the range (reference lines do not). Points that are not positive and
//! finite cannot be drawn on log axes and are skipped; drawing is clipped to each plot area.

use std::fmt::Write;

/// Marker shapes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Marker {
    Circle,
    Square,
    Diamond,
    TriangleUp,
    TriangleDown,
    Cross,
}

impl Marker {
    /// Distinct shapes, for cycling through.
    pub const ALL: [Marker; 6] = [
        Marker::Circle,
        Marker::Square,
        Marker::Diamond,
        Marker::TriangleUp,
        Marker::TriangleDown,
        Marker::Cross,
    ];
}

/// How the points of a series are joined.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Line {
    None,
    Solid,
    Dashed,
}

/// Colour, marker and line of a series.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Style {
    /// An SVG colour (`#rrggbb`).
    pub color: &'static str,
    pub marker: Option<Marker>,
    /// Filled marker, or hollow (white inside).
    pub filled: bool,
    pub line: Line,
}

/// Colour-blind-safe colours (Okabe–Ito), in the order they are handed out.
pub const COLORS: [&str; 7] = [
    "#0072b2", "#e69f00", "#009e73", "#cc79a7", "#d55e00", "#56b4e9", "#000000",
];
/// Reference lines.
pub const GREY: &str = "#777777";

/// Points drawn in one style.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend text; empty: not in the legend (entries with the same text are listed once).
    pub label: String,
    pub style: Style,
    pub points: Vec<(f64, f64)>,
    /// Whether the axis ranges are fitted to these points (false for reference lines).
    pub sets_range: bool,
    /// Text written beside the last point that falls inside the plot area.
    pub tag: Option<String>,
}

impl Series {
    pub fn new(label: impl Into<String>, style: Style, points: Vec<(f64, f64)>) -> Series {
        Series {
            label: label.into(),
            style,
            points,
            sets_range: true,
            tag: None,
        }
    }

    /// A dashed grey reference line that does not stretch the axes.
    pub fn reference(label: impl Into<String>, points: Vec<(f64, f64)>) -> Series {
        Series {
            label: label.into(),
            style: Style {
                color: GREY,
                marker: None,
                filled: false,
                line: Line::Dashed,
            },
            points,
            sets_range: false,
            tag: None,
        }
    }

    /// The same series with `tag` written at its last visible point.
    pub fn tagged(mut self, tag: impl Into<String>) -> Series {
        self.tag = Some(tag.into());
        self
    }
}

/// One plot area.
#[derive(Clone, Debug, Default)]
pub struct Panel {
    pub title: String,
    pub series: Vec<Series>,
    /// Lines of text in the plot area's top left corner.
    pub notes: Vec<String>,
}

/// Panels in a grid with shared log-log axes, a legend on the right and notes below.
#[derive(Clone, Debug, Default)]
pub struct Figure {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub panels: Vec<Panel>,
    /// Panels per row (at least 1).
    pub columns: usize,
    /// Lines of text under the legend.
    pub legend_notes: Vec<String>,
    /// Lines of text under the panels.
    pub notes: Vec<String>,
    /// Width and height of one panel's cell (px); `None`: 400 × 300.
    pub panel_size: Option<(f64, f64)>,
}

const PANEL_SIZE: (f64, f64) = (400.0, 300.0);
/// Inside a panel cell: room for tick labels and axis titles.
const MARGIN_L: f64 = 72.0;
const MARGIN_R: f64 = 16.0;
const MARGIN_T: f64 = 26.0;
const MARGIN_B: f64 = 48.0;
const TITLE_H: f64 = 34.0;
const LEGEND_W: f64 = 290.0;
const LINE_H: f64 = 16.0;

/// Whole decades `(lo, hi)` (exponents) around the positive finite values; `(0, 1)` for none.
fn decades(values: impl Iterator<Item = f64>) -> (i32, i32) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite() && *v > 0.0) {
        lo = lo.min(v.log10());
        hi = hi.max(v.log10());
    }
    if lo > hi {
        return (0, 1);
    }
    // A point a hair above a decade (rounding of 10^k) stays on that decade.
    let lo = (lo + 1e-9).floor() as i32;
    let hi = ((hi - 1e-9).ceil() as i32).max(lo + 1);
    (lo, hi)
}

/// Escapes text for XML content and attributes.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            _ => out.push(c),
        }
    }
    out
}

/// `10ⁿ` as text with a superscript.
fn power_label(exponent: i32) -> String {
    format!("10<tspan dy=\"-6\" font-size=\"9\">{exponent}</tspan>")
}

/// One axis: data to pixels on a log scale.
#[derive(Clone, Copy)]
struct Axis {
    lo: i32,
    hi: i32,
    /// Pixel positions of `10^lo` and `10^hi`.
    from: f64,
    to: f64,
}

impl Axis {
    fn map(&self, value: f64) -> f64 {
        let t = (value.log10() - f64::from(self.lo)) / f64::from(self.hi - self.lo);
        self.from + t * (self.to - self.from)
    }

    /// Every decade when there are few, every other (or more) when there are many.
    fn label_step(&self) -> i32 {
        ((self.hi - self.lo) + 7) / 8
    }
}

fn marker_svg(out: &mut String, marker: Marker, x: f64, y: f64, color: &str, filled: bool) {
    let fill = if filled { color } else { "#ffffff" };
    let r = 3.8;
    let common = format!("fill=\"{fill}\" stroke=\"{color}\" stroke-width=\"1.3\"");
    let poly = |points: &[(f64, f64)]| {
        let p: Vec<String> = points
            .iter()
            .map(|(dx, dy)| format!("{:.2},{:.2}", x + dx, y + dy))
            .collect();
        format!("<polygon points=\"{}\" {common}/>", p.join(" "))
    };
    let element = match marker {
        Marker::Circle => format!("<circle cx=\"{x:.2}\" cy=\"{y:.2}\" r=\"{r}\" {common}/>"),
        Marker::Square => format!(
            "<rect x=\"{:.2}\" y=\"{:.2}\" width=\"{s:.2}\" height=\"{s:.2}\" {common}/>",
            x - r * 0.9,
            y - r * 0.9,
            s = 1.8 * r
        ),
        Marker::Diamond => poly(&[(0.0, -1.3 * r), (1.3 * r, 0.0), (0.0, 1.3 * r), (-1.3 * r, 0.0)]),
        Marker::TriangleUp => poly(&[(0.0, -1.25 * r), (1.1 * r, 0.8 * r), (-1.1 * r, 0.8 * r)]),
        Marker::TriangleDown => poly(&[(0.0, 1.25 * r), (1.1 * r, -0.8 * r), (-1.1 * r, -0.8 * r)]),
        Marker::Cross => format!(
            "<path d=\"M{:.2},{:.2}L{:.2},{:.2}M{:.2},{:.2}L{:.2},{:.2}\" stroke=\"{color}\" stroke-width=\"1.6\" fill=\"none\"/>",
            x - r, y - r, x + r, y + r, x - r, y + r, x + r, y - r
        ),
    };
    out.push_str(&element);
    out.push('\n');
}

fn dash(line: Line) -> &'static str {
    match line {
        Line::Dashed => " stroke-dasharray=\"6,4\"",
        Line::None | Line::Solid => "",
    }
}

impl Figure {
    /// The figure as an SVG document.
    pub fn to_svg(&self) -> String {
        let columns = self.columns.max(1);
        let (panel_w, panel_h) = self.panel_size.unwrap_or(PANEL_SIZE);
        let rows = self.panels.len().div_ceil(columns).max(1);
        let width = columns as f64 * panel_w + LEGEND_W;
        let height = TITLE_H + rows as f64 * panel_h + LINE_H * self.notes.len() as f64 + 12.0;
        let all = || {
            self.panels
                .iter()
                .flat_map(|p| &p.series)
                .filter(|s| s.sets_range)
                .flat_map(|s| &s.points)
        };
        let (x_lo, x_hi) = decades(all().map(|p| p.0));
        let (y_lo, y_hi) = decades(all().map(|p| p.1));

        let mut out = String::new();
        let _ = writeln!(
            out,
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" \
             width=\"{width:.0}\" height=\"{height:.0}\" viewBox=\"0 0 {width:.0} {height:.0}\" \
             font-family=\"DejaVu Sans, Helvetica, Arial, sans-serif\" font-size=\"12\">"
        );
        let _ = writeln!(out, "<title>{}</title>", escape(&self.title));
        let _ = writeln!(
            out,
            "<rect width=\"100%\" height=\"100%\" fill=\"#ffffff\"/>"
        );
        let _ = writeln!(
            out,
            "<text x=\"{:.1}\" y=\"22\" font-size=\"16\" font-weight=\"bold\">{}</text>",
            12.0,
            escape(&self.title)
        );
        for (index, panel) in self.panels.iter().enumerate() {
            let cell_x = (index % columns) as f64 * panel_w;
            let cell_y = TITLE_H + (index / columns) as f64 * panel_h;
            let left = cell_x + MARGIN_L;
            let top = cell_y + MARGIN_T;
            let (w, h) = (panel_w - MARGIN_L - MARGIN_R, panel_h - MARGIN_T - MARGIN_B);
            let x = Axis {
                lo: x_lo,
                hi: x_hi,
                from: left,
                to: left + w,
            };
            let y = Axis {
                lo: y_lo,
                hi: y_hi,
                from: top + h,
                to: top,
            };
            self.panel_svg(&mut out, index, panel, x, y, (left, top, w, h));
        }
        self.legend_svg(&mut out, columns as f64 * panel_w + 8.0, TITLE_H + MARGIN_T);
        let notes_top = TITLE_H + rows as f64 * panel_h + 4.0;
        for (i, note) in self.notes.iter().enumerate() {
            let _ = writeln!(
                out,
                "<text x=\"12\" y=\"{:.1}\" font-size=\"11\" fill=\"#333333\">{}</text>",
                notes_top + LINE_H * (i as f64 + 0.5),
                escape(note)
            );
        }
        out.push_str("</svg>\n");
        out
    }

    fn panel_svg(
        &self,
        out: &mut String,
        index: usize,
        panel: &Panel,
        x: Axis,
        y: Axis,
        (left, top, w, h): (f64, f64, f64, f64),
    ) {
        let _ = writeln!(out, "<g>");
        let _ = writeln!(
            out,
            "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"13\" font-weight=\"bold\" text-anchor=\"middle\">{}</text>",
            left + w / 2.0,
            top - 8.0,
            escape(&panel.title)
        );
        // Grid at the decades, minor ticks at 2…9 × 10^k, tick labels.
        let mut grid = String::new();
        let mut ticks = String::new();
        for k in x.lo..=x.hi {
            let px = x.map(10f64.powi(k));
            let _ = write!(grid, "M{px:.2},{top:.2}V{:.2}", top + h);
            let _ = write!(ticks, "M{px:.2},{:.2}v6", top + h);
            if (k - x.lo) % x.label_step() == 0 {
                let _ = writeln!(
                    out,
                    "<text x=\"{px:.2}\" y=\"{:.2}\" text-anchor=\"middle\">{}</text>",
                    top + h + 20.0,
                    power_label(k)
                );
            }
        }
        for k in y.lo..=y.hi {
            let py = y.map(10f64.powi(k));
            let _ = write!(grid, "M{left:.2},{py:.2}H{:.2}", left + w);
            let _ = write!(ticks, "M{left:.2},{py:.2}h-6");
            if (k - y.lo) % y.label_step() == 0 {
                let _ = writeln!(
                    out,
                    "<text x=\"{:.2}\" y=\"{:.2}\" text-anchor=\"end\">{}</text>",
                    left - 9.0,
                    py + 4.0,
                    power_label(k)
                );
            }
        }
        let minor = |axis: &Axis| -> Vec<f64> {
            if axis.hi - axis.lo > 8 {
                return Vec::new();
            }
            (axis.lo..axis.hi)
                .flat_map(|k| (2..10).map(move |m| f64::from(m) * 10f64.powi(k)))
                .map(|v| axis.map(v))
                .collect()
        };
        for px in minor(&x) {
            let _ = write!(ticks, "M{px:.2},{:.2}v3", top + h);
        }
        for py in minor(&y) {
            let _ = write!(ticks, "M{left:.2},{py:.2}h-3");
        }
        let _ = writeln!(
            out,
            "<path d=\"{grid}\" stroke=\"#e3e3e3\" stroke-width=\"1\" fill=\"none\"/>\n\
             <path d=\"{ticks}\" stroke=\"#000000\" stroke-width=\"1\" fill=\"none\"/>\n\
             <rect x=\"{left:.2}\" y=\"{top:.2}\" width=\"{w:.2}\" height=\"{h:.2}\" fill=\"none\" stroke=\"#000000\"/>"
        );
        // Axis titles.
        let _ = writeln!(
            out,
            "<text x=\"{:.2}\" y=\"{:.2}\" text-anchor=\"middle\">{}</text>",
            left + w / 2.0,
            top + h + 40.0,
            escape(&self.x_label)
        );
        let (ly_x, ly_y) = (left - 50.0, top + h / 2.0);
        let _ = writeln!(
            out,
            "<text x=\"{ly_x:.2}\" y=\"{ly_y:.2}\" text-anchor=\"middle\" transform=\"rotate(-90 {ly_x:.2} {ly_y:.2})\">{}</text>",
            escape(&self.y_label)
        );
        // The data, clipped to the plot area (markers may reach a little beyond it).
        let _ = writeln!(
            out,
            "<clipPath id=\"clip{index}\"><rect x=\"{:.2}\" y=\"{:.2}\" width=\"{:.2}\" height=\"{:.2}\"/></clipPath>\n<g clip-path=\"url(#clip{index})\">",
            left - 5.0,
            top - 5.0,
            w + 10.0,
            h + 10.0
        );
        for series in &panel.series {
            let points: Vec<(f64, f64)> = series
                .points
                .iter()
                .filter(|(a, b)| a.is_finite() && b.is_finite() && *a > 0.0 && *b > 0.0)
                .map(|&(a, b)| (x.map(a), y.map(b)))
                .collect();
            let style = series.style;
            if style.line != Line::None && points.len() >= 2 {
                let p: Vec<String> = points
                    .iter()
                    .map(|(a, b)| format!("{a:.2},{b:.2}"))
                    .collect();
                let _ = writeln!(
                    out,
                    "<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\"{}/>",
                    p.join(" "),
                    style.color,
                    dash(style.line)
                );
            }
            if let Some(marker) = style.marker {
                for &(a, b) in &points {
                    marker_svg(out, marker, a, b, style.color, style.filled);
                }
            }
            let inside = |(a, b): &&(f64, f64)| {
                (left - 0.5..=left + w + 0.5).contains(a) && (top - 0.5..=top + h + 0.5).contains(b)
            };
            if let (Some(tag), Some(&(a, b))) = (&series.tag, points.iter().rev().find(inside)) {
                // Towards the inside of the plot area from whichever edge the point is near.
                let anchor = if a > left + w - 60.0 { "end" } else { "start" };
                let dx = if anchor == "end" { -4.0 } else { 4.0 };
                let dy = if b > top + h - 14.0 { -5.0 } else { 12.0 };
                let _ = writeln!(
                    out,
                    "<text x=\"{:.2}\" y=\"{:.2}\" font-size=\"11\" fill=\"{}\" text-anchor=\"{anchor}\">{}</text>",
                    a + dx,
                    b + dy,
                    style.color,
                    escape(tag)
                );
            }
        }
        let _ = writeln!(out, "</g>");
        for (i, note) in panel.notes.iter().enumerate() {
            let _ = writeln!(
                out,
                "<text x=\"{:.2}\" y=\"{:.2}\" font-size=\"10.5\" fill=\"#333333\">{}</text>",
                left + 6.0,
                top + 14.0 + LINE_H * 0.85 * i as f64,
                escape(note)
            );
        }
        let _ = writeln!(out, "</g>");
    }

    fn legend_svg(&self, out: &mut String, left: f64, top: f64) {
        let mut seen: Vec<&str> = Vec::new();
        let mut row = 0.0;
        let _ = writeln!(out, "<g>");
        for series in self.panels.iter().flat_map(|p| &p.series) {
            if series.label.is_empty() || seen.contains(&series.label.as_str()) {
                continue;
            }
            seen.push(&series.label);
            let cy = top + row * LINE_H;
            let style = series.style;
            if style.line != Line::None {
                let _ = writeln!(
                    out,
                    "<line x1=\"{left:.2}\" y1=\"{cy:.2}\" x2=\"{:.2}\" y2=\"{cy:.2}\" stroke=\"{}\" stroke-width=\"1.5\"{}/>",
                    left + 26.0,
                    style.color,
                    dash(style.line)
                );
            }
            if let Some(marker) = style.marker {
                marker_svg(out, marker, left + 13.0, cy, style.color, style.filled);
            }
            let _ = writeln!(
                out,
                "<text x=\"{:.2}\" y=\"{:.2}\">{}</text>",
                left + 32.0,
                cy + 4.0,
                escape(&series.label)
            );
            row += 1.0;
        }
        row += 0.5;
        for note in &self.legend_notes {
            let _ = writeln!(
                out,
                "<text x=\"{left:.2}\" y=\"{:.2}\" font-size=\"11\" fill=\"#333333\">{}</text>",
                top + row * LINE_H + 4.0,
                escape(note)
            );
            row += 1.0;
        }
        let _ = writeln!(out, "</g>");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decades_enclose_the_data() {
        assert_eq!(decades([3.0, 450.0].into_iter()), (0, 3));
        assert_eq!(decades([1e-16, 1e-3].into_iter()), (-16, -3));
        assert_eq!(decades([5.0].into_iter()), (0, 1));
        assert_eq!(decades([0.0, -1.0, f64::NAN].into_iter()), (0, 1));
    }

    #[test]
    fn axis_maps_decades_linearly_in_the_exponent() {
        let axis = Axis {
            lo: 0,
            hi: 4,
            from: 100.0,
            to: 500.0,
        };
        assert!((axis.map(1.0) - 100.0).abs() < 1e-9);
        assert!((axis.map(100.0) - 300.0).abs() < 1e-9);
        assert!((axis.map(1e4) - 500.0).abs() < 1e-9);
    }

    #[test]
    fn text_is_escaped() {
        assert_eq!(escape("a<b & \"c\">"), "a&lt;b &amp; &quot;c&quot;&gt;");
    }
}
