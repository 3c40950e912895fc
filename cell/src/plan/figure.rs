//! Figure 5.9 of seed 001 ("Payout Eye Collision Avoidance") as SVG text: in the mandrel frame,
//! a side view (`x` across, `z` up) and a top view (`x` across, `y` up) of the mandrel's circular
//! sections at every tangent point (§5.7: "Each circular cross-section is located at a point on
//! the desired fibre path"), the spine, the tangent points, the eye path and the tow lines of
//! every path, the eye mechanism and the arm's links at the worst pose, the cell's obstacles
//! (boxes in the cell frame, seen from the mandrel at the worst pose's angle), and every finding
//! in red.
//!
//! Written as text: the figure is lines, circles and polylines, and an SVG crate would add a
//! dependency for what `format!` does (docs/ARCHITECTURE.md, "External crates and why").

use std::fmt::Write;

use nalgebra::Point3;

use crate::plan::check::Checked;

/// Width and height of each view, px.
const VIEW_PX: f64 = 520.0;
/// Margin around and between views, px.
const MARGIN_PX: f64 = 30.0;

/// Colours of the paths' eye paths, in turn.
const PATH_COLOURS: [&str; 4] = ["#1f77b4", "#2ca02c", "#9467bd", "#8c564b"];

/// A cell-frame point in the mandrel frame at mandrel angle `phi`.
fn to_mandrel(checked: &Checked, p: &Point3<f64>, phi: f64) -> Point3<f64> {
    checked.to_mandrel(p, phi)
}

/// One view: which two mandrel-frame axes it shows.
#[derive(Clone, Copy)]
struct View {
    left_px: f64,
    across: usize,
    up: usize,
    scale: f64,
    lo: [f64; 3],
}

impl View {
    fn x(&self, p: &Point3<f64>) -> f64 {
        self.left_px + MARGIN_PX + (p[self.across] - self.lo[self.across]) * self.scale
    }
    fn y(&self, p: &Point3<f64>) -> f64 {
        MARGIN_PX + VIEW_PX - (p[self.up] - self.lo[self.up]) * self.scale
    }
}

/// The figure as an SVG document: the two views side by side, each with its axes in mm, then
/// the legend and the check's summary.
pub fn svg(checked: &Checked) -> String {
    let worst_links = worst_links(checked);
    let (side, top) = views(checked, &worst_links);
    let width = 2.0 * VIEW_PX + 3.0 * MARGIN_PX;
    let height = VIEW_PX + 2.0 * MARGIN_PX + LEGEND_PX + 20.0;
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0}" height="{height:.0}" viewBox="0 0 {width:.0} {height:.0}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        s,
        "<title>Payout eye collision avoidance (seed 001 Figure 5.9): {}</title>",
        escape(&crate::plan::check::summary(checked))
    );
    for (view, name) in [
        (side, "side view (x, z), mandrel frame, mm"),
        (top, "top view (x, y), mandrel frame, mm"),
    ] {
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{:.1}">{name}</text>"#,
            view.left_px + MARGIN_PX,
            MARGIN_PX - 10.0
        );
        axes(&mut s, &view);
        // Nothing is drawn outside the view's frame (an arm link's capsule can be larger).
        let clip = format!("view{:.0}", view.left_px);
        let _ = writeln!(
            s,
            r#"<clipPath id="{clip}"><rect x="{:.1}" y="{MARGIN_PX:.1}" width="{VIEW_PX:.0}" height="{VIEW_PX:.0}"/></clipPath><g clip-path="url(#{clip})">"#,
            view.left_px + MARGIN_PX
        );
        // The arm and the obstacles first, so that the mandrel and the paths are drawn over
        // them.
        arm(&mut s, &view, &worst_links);
        obstacles(&mut s, checked, &view);
        sections(&mut s, checked, &view);
        spine_and_axis(&mut s, checked, &view);
        fibre_paths(&mut s, checked, &view);
        findings(&mut s, checked, &view);
        let _ = writeln!(s, "</g>");
    }
    legend(&mut s, checked, VIEW_PX + 2.0 * MARGIN_PX + 10.0);
    let _ = writeln!(
        s,
        r#"<text x="{MARGIN_PX:.0}" y="{:.0}">{}</text>"#,
        height - 8.0,
        escape(&crate::plan::check::summary(checked))
    );
    s.push_str("</svg>\n");
    s
}

/// Height of the legend under the views, px.
const LEGEND_PX: f64 = 40.0;

/// The side and top views, on one scale each, over everything drawn (the poses, and the arm at
/// the worst pose) with a mandrel radius around it.
fn views(checked: &Checked, worst_links: &[(Point3<f64>, Point3<f64>, f64)]) -> (View, View) {
    let r = checked.tube.radius_mm();
    let mut points: Vec<Point3<f64>> = Vec::new();
    for p in &checked.plan.paths {
        for pose in std::iter::once(&p.plan.start).chain(p.plan.segments.iter().map(|s| &s.pose)) {
            points.push(pose.tangent_point_mm);
            points.push(pose.eye_mandrel_mm);
        }
    }
    for (a, b, _) in worst_links {
        points.push(*a);
        points.push(*b);
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in &points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k] - r);
            hi[k] = hi[k].max(p[k] + r);
        }
    }
    if !lo[0].is_finite() {
        lo = [-1.0; 3];
        hi = [1.0; 3];
    }
    let side_scale = VIEW_PX / (hi[0] - lo[0]).max(hi[2] - lo[2]).max(1e-9);
    let top_scale = VIEW_PX / (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-9);
    let side = View {
        left_px: 0.0,
        across: 0,
        up: 2,
        scale: side_scale,
        lo,
    };
    let top = View {
        left_px: VIEW_PX + MARGIN_PX,
        across: 0,
        up: 1,
        scale: top_scale,
        lo,
    };
    (side, top)
}

/// The view's frame with ticks and labels every round number of mm, and the origin's lines.
fn axes(s: &mut String, view: &View) {
    let (x0, y0) = (view.left_px + MARGIN_PX, MARGIN_PX);
    let _ = writeln!(
        s,
        r##"<rect x="{x0:.1}" y="{y0:.1}" width="{VIEW_PX:.0}" height="{VIEW_PX:.0}" fill="none" stroke="#dddddd"/>"##
    );
    let span_mm = VIEW_PX / view.scale;
    let step_mm = tick_step_mm(span_mm);
    let _ = writeln!(s, r##"<g stroke="#999999" fill="#555555" font-size="9">"##);
    for (axis, horizontal) in [(view.across, true), (view.up, false)] {
        let lo = view.lo[axis];
        let mut t = (lo / step_mm).ceil() * step_mm;
        while t <= lo + span_mm + 1e-9 {
            let px = (t - lo) * view.scale;
            // Rounded to the µm, and never "-0".
            let label = format!("{}", (t * 1e6).round() / 1e6 + 0.0);
            if horizontal {
                let x = x0 + px;
                let y = y0 + VIEW_PX;
                let _ = writeln!(
                    s,
                    r#"<line x1="{x:.1}" y1="{y:.1}" x2="{x:.1}" y2="{:.1}"/><text x="{x:.1}" y="{:.1}" text-anchor="middle" stroke="none">{label}</text>"#,
                    y + 4.0,
                    y + 13.0
                );
            } else {
                let y = y0 + VIEW_PX - px;
                let _ = writeln!(
                    s,
                    r#"<line x1="{:.1}" y1="{y:.1}" x2="{x0:.1}" y2="{y:.1}"/><text x="{:.1}" y="{:.1}" text-anchor="end" stroke="none">{label}</text>"#,
                    x0 - 4.0,
                    x0 - 5.0,
                    y + 3.0
                );
            }
            t += step_mm;
        }
    }
    let _ = writeln!(s, "</g>");
}

/// A round tick spacing (1, 2 or 5 × 10ⁿ mm) giving about six ticks over `span_mm`.
fn tick_step_mm(span_mm: f64) -> f64 {
    let raw = (span_mm / 6.0).max(1e-9);
    let decade = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|step| *step >= raw)
        .unwrap_or(10.0 * decade)
}

/// What each colour and line means.
fn legend(s: &mut String, checked: &Checked, y: f64) {
    let mut x = MARGIN_PX;
    let mut y = y;
    let right = 2.0 * VIEW_PX + 2.0 * MARGIN_PX;
    let mut entry = |s: &mut String, style: &str, text: &str| {
        // About 7 px per character at 12 px: a new row where the entry would not fit.
        let width = 34.0 + 7.0 * text.chars().count() as f64;
        if x + width > right {
            x = MARGIN_PX;
            y += 18.0;
        }
        let _ = writeln!(
            s,
            r#"<line x1="{x:.1}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" {style}/><text x="{:.1}" y="{:.1}">{text}</text>"#,
            x + 22.0,
            x + 26.0,
            y + 4.0
        );
        x += width;
    };
    for (i, p) in checked.plan.paths.iter().enumerate() {
        let colour = PATH_COLOURS[i % PATH_COLOURS.len()];
        entry(
            s,
            &format!(r#"stroke="{colour}" stroke-width="1.2""#),
            &format!("eye path, {}", escape(&p.name)),
        );
    }
    entry(s, r##"stroke="#ff7f0e""##, "tow line");
    entry(s, r##"stroke="#bbbbbb""##, "mandrel section");
    entry(s, r##"stroke="#555555" stroke-dasharray="4 3""##, "spine");
    entry(
        s,
        r##"stroke="#000000" stroke-dasharray="10 3 2 3""##,
        "rotation axis",
    );
    entry(
        s,
        r##"stroke="#7f7f7f" stroke-opacity="0.45" stroke-width="6""##,
        "arm, worst pose",
    );
    if !checked.obstacles.is_empty() {
        entry(
            s,
            r##"stroke="#8c6d31" stroke-width="1.2""##,
            "obstacle, at the worst pose's mandrel angle",
        );
    }
    entry(s, r##"stroke="#d62728" stroke-width="2.5""##, "finding");
}

/// Each obstacle's box (cell frame, fixed) seen from the mandrel at the worst pose's angle, the
/// angle the arm is drawn at: its twelve edges.
fn obstacles(s: &mut String, checked: &Checked, view: &View) {
    let phi = checked.report.worst.map_or(0.0, |w| w.mandrel_rad);
    for o in &checked.obstacles {
        let corner = |bits: usize| {
            let pick = |k: usize| {
                if bits >> k & 1 == 0 {
                    o.min_mm[k]
                } else {
                    o.max_mm[k]
                }
            };
            to_mandrel(checked, &Point3::new(pick(0), pick(1), pick(2)), phi)
        };
        let _ = writeln!(s, "<g><title>{}</title>", escape(&o.name));
        for a in 0..8usize {
            for k in 0..3 {
                let b = a | 1 << k;
                if b != a {
                    line(
                        s,
                        view,
                        &corner(a),
                        &corner(b),
                        r##"stroke="#8c6d31" stroke-width="1.2" fill="none""##,
                    );
                }
            }
        }
        let _ = writeln!(s, "</g>");
    }
}

/// The mandrel's circular sections at every tangent point (§5.7).
fn sections(s: &mut String, checked: &Checked, view: &View) {
    let _ = writeln!(
        s,
        r##"<g fill="none" stroke="#bbbbbb" stroke-width="0.6">"##
    );
    let tube = &checked.tube;
    let r = tube.radius_mm();
    // Sections at every tangent point.
    for p in &checked.plan.paths {
        for pose in std::iter::once(&p.plan.start).chain(p.plan.segments.iter().map(|s| &s.pose)) {
            let section = tube.section(pose.tangent_point_mm.z);
            let c = Point3::new(
                section.centroid_mm.x,
                section.centroid_mm.y,
                pose.tangent_point_mm.z,
            );
            if view.up == 2 {
                let a = Point3::new(c.x - r, c.y, c.z);
                let b = Point3::new(c.x + r, c.y, c.z);
                line(s, view, &a, &b, "");
            } else {
                let _ = writeln!(
                    s,
                    r#"<circle cx="{:.2}" cy="{:.2}" r="{:.2}"/>"#,
                    view.x(&c),
                    view.y(&c),
                    r * view.scale
                );
            }
        }
    }
    let _ = writeln!(s, "</g>");
}

/// The spine (the sections' centres) and the rotation axis (the mandrel frame's z axis).
fn spine_and_axis(s: &mut String, checked: &Checked, view: &View) {
    let tube = &checked.tube;
    // The spine.
    let spine: Vec<Point3<f64>> = (0..=100)
        .map(|i| {
            let z = tube.u_min() + (tube.u_max() - tube.u_min()) * i as f64 / 100.0;
            Point3::new(tube.spine().offset_mm(z), 0.0, z)
        })
        .collect();
    polyline(
        s,
        view,
        &spine,
        r##"stroke="#555555" stroke-dasharray="4 3""##,
    );
    let axis = [
        Point3::new(0.0, 0.0, tube.u_min()),
        Point3::new(0.0, 0.0, tube.u_max()),
    ];
    if view.up == 2 {
        polyline(
            s,
            view,
            &axis,
            r##"stroke="#000000" stroke-dasharray="10 3 2 3""##,
        );
    } else {
        let _ = writeln!(
            s,
            r##"<circle cx="{:.2}" cy="{:.2}" r="3" fill="none" stroke="#000000"/>"##,
            view.x(&axis[0]),
            view.y(&axis[0])
        );
    }
}

/// Each path: its tow lines, eye path and tangent points.
fn fibre_paths(s: &mut String, checked: &Checked, view: &View) {
    for (i, p) in checked.plan.paths.iter().enumerate() {
        let colour = PATH_COLOURS[i % PATH_COLOURS.len()];
        let poses: Vec<&paths::Pose> = std::iter::once(&p.plan.start)
            .chain(p.plan.segments.iter().map(|s| &s.pose))
            .collect();
        let _ = writeln!(s, r##"<g stroke="#ff7f0e" stroke-width="0.4">"##);
        for pose in &poses {
            line(s, view, &pose.tangent_point_mm, &pose.eye_mandrel_mm, "");
        }
        let _ = writeln!(s, "</g>");
        let eyes: Vec<Point3<f64>> = poses.iter().map(|p| p.eye_mandrel_mm).collect();
        polyline(
            s,
            view,
            &eyes,
            &format!(r#"stroke="{colour}" stroke-width="1.2""#),
        );
        let _ = writeln!(s, r#"<g fill="{colour}">"#);
        for pose in &poses {
            let _ = writeln!(
                s,
                r#"<circle cx="{:.2}" cy="{:.2}" r="1.3"/>"#,
                view.x(&pose.tangent_point_mm),
                view.y(&pose.tangent_point_mm)
            );
        }
        let _ = writeln!(s, "</g>");
    }
}

/// The eye mechanism and the arm's links at the worst pose, drawn first (behind the mandrel).
fn arm(s: &mut String, view: &View, worst_links: &[(Point3<f64>, Point3<f64>, f64)]) {
    for (a, b, radius) in worst_links {
        let _ = writeln!(
            s,
            r##"<line x1="{:.2}" y1="{:.2}" x2="{:.2}" y2="{:.2}" stroke="#7f7f7f" stroke-opacity="0.45" stroke-linecap="round" stroke-width="{:.2}"/>"##,
            view.x(a),
            view.y(a),
            view.x(b),
            view.y(b),
            (2.0 * radius * view.scale).max(1.0)
        );
    }
}

/// Every finding in red: the eye mechanism (or the tow line) where it happened.
fn findings(s: &mut String, checked: &Checked, view: &View) {
    for f in &checked.report.findings {
        let eye = to_mandrel(checked, &f.eye_mm, f.mandrel_rad);
        let axis = checked.direction_to_mandrel(&f.axis, f.mandrel_rad);
        let back = eye - axis * checked.eye.length_mm;
        line(
            s,
            view,
            &eye,
            &back,
            r##"stroke="#d62728" stroke-width="2.5""##,
        );
        let _ = writeln!(
            s,
            r##"<circle cx="{:.2}" cy="{:.2}" r="6" fill="none" stroke="#d62728" stroke-width="1.5"/>"##,
            view.x(&eye),
            view.y(&eye)
        );
    }
}

/// The eye mechanism and the arm's links at the worst pose, mandrel frame: `(a, b, radius)`.
fn worst_links(checked: &Checked) -> Vec<(Point3<f64>, Point3<f64>, f64)> {
    let Some(w) = checked.report.worst else {
        return Vec::new();
    };
    let mut out = vec![(
        to_mandrel(checked, &w.eye_mm, w.mandrel_rad),
        to_mandrel(
            checked,
            &(w.eye_mm - w.axis * checked.eye.length_mm),
            w.mandrel_rad,
        ),
        checked.eye.radius_mm,
    )];
    for link in checked.links_at(&w.eye_mm, &w.axis, w.joints.as_ref()) {
        out.push((
            to_mandrel(checked, &link.a, w.mandrel_rad),
            to_mandrel(checked, &link.b, w.mandrel_rad),
            link.radius_mm,
        ));
    }
    out
}

fn line(s: &mut String, view: &View, a: &Point3<f64>, b: &Point3<f64>, style: &str) {
    let _ = writeln!(
        s,
        r#"<line x1="{:.2}" y1="{:.2}" x2="{:.2}" y2="{:.2}" {style}/>"#,
        view.x(a),
        view.y(a),
        view.x(b),
        view.y(b)
    );
}

fn polyline(s: &mut String, view: &View, points: &[Point3<f64>], style: &str) {
    let _ = write!(s, r#"<polyline fill="none" {style} points=""#);
    for p in points {
        let _ = write!(s, "{:.2},{:.2} ", view.x(p), view.y(p));
    }
    let _ = writeln!(s, r#""/>"#);
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::tick_step_mm;

    #[test]
    fn ticks_are_one_two_or_five_times_a_power_of_ten_near_a_sixth_of_the_span() {
        // span / 6, rounded up to the next of 1, 2, 5, 10 × 10ⁿ (worked by hand).
        assert_eq!(tick_step_mm(600.0), 100.0);
        assert_eq!(tick_step_mm(130.0), 50.0); // 21.7 → 50
        assert_eq!(tick_step_mm(100.0), 20.0); // 16.7 → 20
        assert_eq!(tick_step_mm(6.0), 1.0);
        assert!((tick_step_mm(0.9) - 0.2).abs() < 1e-12); // 0.15 → 0.2
        assert_eq!(tick_step_mm(5400.0), 1000.0); // 900 → 1000
    }
}
