//! Figure 5.9 of seed 001 ("Payout Eye Collision Avoidance") as SVG text: in the mandrel frame,
//! a side view (`x` across, `z` up) and a top view (`x` across, `y` up) of the mandrel's circular
//! sections at every tangent point (§5.7: "Each circular cross-section is located at a point on
//! the desired fibre path"), the spine, the tangent points, the eye path and the tow lines of
//! every path, the eye mechanism and the arm's links at the worst pose, and every finding in red.
//!
//! Written as text: the figure is lines, circles and polylines, and an SVG crate would add a
//! dependency for what `format!` does (docs/ARCHITECTURE.md, "External crates and why").

use std::fmt::Write;

use nalgebra::{Point3, Vector3};

use crate::plan::check::Checked;

/// Width and height of each view, px.
const VIEW_PX: f64 = 520.0;
/// Margin around and between views, px.
const MARGIN_PX: f64 = 30.0;

/// Colours of the paths' eye paths, in turn.
const PATH_COLOURS: [&str; 4] = ["#1f77b4", "#2ca02c", "#9467bd", "#8c564b"];

/// A cell-frame point in the mandrel frame at mandrel angle `phi`.
fn to_mandrel(checked: &Checked, p: &Point3<f64>, phi: f64) -> Point3<f64> {
    let setup = &checked.setup;
    let w = p - Vector3::new(setup.robot_distance_mm, 0.0, setup.mandrel_height_mm);
    let (s, c) = phi.sin_cos();
    Point3::new(c * w.x + s * w.y, -s * w.x + c * w.y, w.z)
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

/// The figure as an SVG document.
pub fn svg(checked: &Checked) -> String {
    let tube = &checked.tube;
    let r = tube.radius_mm();
    // Everything drawn, for the bounds.
    let mut points: Vec<Point3<f64>> = Vec::new();
    for p in &checked.plan.paths {
        for pose in std::iter::once(&p.plan.start).chain(p.plan.segments.iter().map(|s| &s.pose)) {
            points.push(pose.tangent_point_mm);
            points.push(pose.eye_mandrel_mm);
        }
    }
    let worst_links = worst_links(checked);
    for (a, b, _) in &worst_links {
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
    let width = 2.0 * VIEW_PX + 3.0 * MARGIN_PX;
    let height = VIEW_PX + 2.0 * MARGIN_PX + 20.0;
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
        (side, "side view (x, z), mandrel frame"),
        (top, "top view (x, y), mandrel frame"),
    ] {
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{:.1}">{name}</text>"#,
            view.left_px + MARGIN_PX,
            MARGIN_PX - 10.0
        );
        let _ = writeln!(
            s,
            r##"<g fill="none" stroke="#bbbbbb" stroke-width="0.6">"##
        );
        // Sections at every tangent point.
        for p in &checked.plan.paths {
            for pose in
                std::iter::once(&p.plan.start).chain(p.plan.segments.iter().map(|s| &s.pose))
            {
                let section = tube.section(pose.tangent_point_mm.z);
                let c = Point3::new(
                    section.centroid_mm.x,
                    section.centroid_mm.y,
                    pose.tangent_point_mm.z,
                );
                if view.up == 2 {
                    let a = Point3::new(c.x - r, c.y, c.z);
                    let b = Point3::new(c.x + r, c.y, c.z);
                    line(&mut s, &view, &a, &b, "");
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
        // The spine.
        let spine: Vec<Point3<f64>> = (0..=100)
            .map(|i| {
                let z = tube.u_min() + (tube.u_max() - tube.u_min()) * i as f64 / 100.0;
                Point3::new(tube.spine().offset_mm(z), 0.0, z)
            })
            .collect();
        polyline(
            &mut s,
            &view,
            &spine,
            r##"stroke="#555555" stroke-dasharray="4 3""##,
        );
        for (i, p) in checked.plan.paths.iter().enumerate() {
            let colour = PATH_COLOURS[i % PATH_COLOURS.len()];
            let poses: Vec<&paths::Pose> = std::iter::once(&p.plan.start)
                .chain(p.plan.segments.iter().map(|s| &s.pose))
                .collect();
            let _ = writeln!(s, r##"<g stroke="#ff7f0e" stroke-width="0.4">"##);
            for pose in &poses {
                line(
                    &mut s,
                    &view,
                    &pose.tangent_point_mm,
                    &pose.eye_mandrel_mm,
                    "",
                );
            }
            let _ = writeln!(s, "</g>");
            let eyes: Vec<Point3<f64>> = poses.iter().map(|p| p.eye_mandrel_mm).collect();
            polyline(
                &mut s,
                &view,
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
        // The arm and the eye mechanism at the worst pose.
        for (a, b, radius) in &worst_links {
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
        // Findings in red: the eye mechanism (or the tow line) where it happened.
        for f in &checked.report.findings {
            let eye = to_mandrel(checked, &f.eye_mm, f.mandrel_rad);
            let axis = rotate(&f.axis, f.mandrel_rad);
            let back = eye - axis * checked.eye.length_mm;
            line(
                &mut s,
                &view,
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
    let _ = writeln!(
        s,
        r#"<text x="{MARGIN_PX:.0}" y="{:.0}">{}</text>"#,
        height - 8.0,
        escape(&crate::plan::check::summary(checked))
    );
    s.push_str("</svg>\n");
    s
}

/// A cell-frame direction in the mandrel frame at angle `phi`.
fn rotate(v: &Vector3<f64>, phi: f64) -> Vector3<f64> {
    let (s, c) = phi.sin_cos();
    Vector3::new(c * v.x + s * v.y, -s * v.x + c * v.y, v.z)
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
    let rho = w.eye_mm.x.hypot(w.eye_mm.y);
    if rho > 1e-9 {
        let across = Vector3::new(-w.eye_mm.y / rho, w.eye_mm.x / rho, 0.0);
        let in_plane = w.axis - across * w.axis.dot(&across);
        if let Some(roll) = nalgebra::Unit::try_new(in_plane, 1e-9)
            && let Ok(j) =
                checked
                    .arm
                    .inverse(&w.eye_mm, &roll, 0.0, crate::plan::check::ELBOW_BRANCH)
        {
            for link in checked.arm.links(&j).iter().take(4) {
                out.push((
                    to_mandrel(checked, &link.a, w.mandrel_rad),
                    to_mandrel(checked, &link.b, w.mandrel_rad),
                    link.radius_mm,
                ));
            }
        }
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
