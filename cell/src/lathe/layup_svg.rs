//! A picture of a lathe layup (`windcell lathe plan … --svg FILE`): the mandrel unwrapped
//! (axial position from the mandrel's start × mandrel angle 0…360°) with every pass of every
//! layer in its layer's colour, the turnarounds (mandrel turns with the carriage still) as grey
//! marks at the ends, a legend of the layers, and the laminate's thickness along the mandrel.
//!
//! The paths are the carriage position against the mandrel angle, where the tow leaves the
//! delivery eye: on tubes, cones and noses (`.wind` jobs) that is where it lies; on a vessel's
//! domes it is the eye's path, not the tow's.
//!
//! Thickness: on tubes, cones and noses, from the tow laid, by conservation of volume
//! (`t(x) = t_ply·b·Σ dl / (2π·r(x)·dm)`: every move over the station adds its band `b` times its
//! length per unit of meridian, spread around the circumference), so a helical layer gives two
//! plies (±α) on a cylinder and more where a cone or nose narrows; on a seed 002 vessel, two plies
//! per helical layer on the cylinder times the dome thickness ratio of seed 002 Eqs. 10–11
//! ([`paths::pattern::dome_thickness_ratio`]) on the domes, and one ply per hoop pass on the
//! cylinder.

use std::fmt::Write as _;

use paths::motion::{LayerKind, LayerMark, MotionSink, Move, MoveKind};
use paths::vessel::{Job, Mandrel, Plan};

/// Stations of the thickness profile along the mandrel.
pub const STATIONS: usize = 400;

const WIDTH: f64 = 1200.0;
const LEFT: f64 = 70.0;
const RIGHT: f64 = 20.0;
const TOP: f64 = 40.0;
const MAP_H: f64 = 420.0;
const GAP: f64 = 60.0;
const PROFILE_H: f64 = 160.0;
const PALETTE: [&str; 8] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2",
];

/// The mandrel's radius at `x_mm` from its start (the end where winding starts), mm.
pub fn radius_at(mandrel: &Mandrel, x_mm: f64) -> f64 {
    match *mandrel {
        Mandrel::Tube { radius_mm, .. } => radius_mm,
        Mandrel::Cone {
            large_radius_mm,
            small_radius_mm,
            length_mm,
        } => {
            large_radius_mm
                - (large_radius_mm - small_radius_mm) * (x_mm / length_mm).clamp(0.0, 1.0)
        }
        // Von Kármán ogive (Haack series, C = 0): r = (R/√π)·√(φ − sin 2φ / 2),
        // φ = acos(1 − 2x'/L), x' = L − x from the tip.
        Mandrel::VonKarman {
            base_radius_mm,
            length_mm,
        } => {
            let from_tip = (length_mm - x_mm).clamp(0.0, length_mm);
            let phi = (1.0 - 2.0 * from_tip / length_mm).clamp(-1.0, 1.0).acos();
            base_radius_mm / std::f64::consts::PI.sqrt()
                * (phi - (2.0 * phi).sin() / 2.0).max(0.0).sqrt()
        }
        Mandrel::Vessel {
            cylinder_radius_mm,
            cylinder_length_mm,
            polar_radius_mm,
        } => {
            let dome = (cylinder_radius_mm.powi(2) - polar_radius_mm.powi(2))
                .max(0.0)
                .sqrt();
            let z = (x_mm - dome)
                .min(0.0)
                .abs()
                .max((x_mm - dome - cylinder_length_mm).max(0.0));
            (cylinder_radius_mm.powi(2) - z * z)
                .max(polar_radius_mm.powi(2))
                .sqrt()
        }
    }
}

/// The moves of a plan by layer, in the planner's frame.
#[derive(Default)]
struct ByLayer {
    marks: Vec<LayerMark>,
    moves: Vec<Vec<Move>>,
    last: Option<Move>,
    starts: Vec<Option<Move>>,
}

impl MotionSink for ByLayer {
    type Error = std::convert::Infallible;
    fn layer(&mut self, mark: &LayerMark) -> Result<(), Self::Error> {
        self.marks.push(*mark);
        self.moves.push(Vec::new());
        self.starts.push(self.last);
        Ok(())
    }
    fn motion(&mut self, m: &Move) -> Result<(), Self::Error> {
        if let Some(layer) = self.moves.last_mut() {
            layer.push(*m);
        }
        self.last = Some(*m);
        Ok(())
    }
}

/// The drawing's figures, for tests and the summary.
#[derive(Debug, Clone, PartialEq)]
pub struct Layup {
    /// Passes drawn (runs of feed moves with the carriage moving one way), per layer.
    pub passes_drawn: Vec<usize>,
    /// Turnaround marks drawn (feed moves turning the mandrel with the carriage still), per
    /// layer.
    pub turns_drawn: Vec<usize>,
    /// Thickness along the mandrel: (x from the start, mm; thickness, mm) per station.
    pub thickness: Vec<(f64, f64)>,
}

/// The map's frame: the mandrel's start in the planner's frame and its length, mm, across the
/// plot's width.
#[derive(Clone, Copy)]
struct MapFrame {
    start_mm: f64,
    length_mm: f64,
    plot_w: f64,
}

impl MapFrame {
    /// Picture x of a carriage position in the planner's frame.
    fn sx(&self, x_mm: f64) -> f64 {
        LEFT + (x_mm - self.start_mm) / self.length_mm * self.plot_w
    }

    /// Picture y of a mandrel angle.
    fn sy(&self, deg: f64) -> f64 {
        TOP + deg / 360.0 * MAP_H
    }
}

/// Draws `plan` of `job` as SVG text; `start_mm` is where the mandrel starts in the planner's
/// frame (`cli::lathe::machine::mandrel_start_mm`), `title` the job's name.
pub fn draw(job: &Job, plan: &Plan, start_mm: f64, title: &str) -> (String, Layup) {
    let mut by = ByLayer::default();
    let Ok(()) = plan.emit(&mut by);
    let frame = MapFrame {
        start_mm,
        length_mm: -2.0 * start_mm,
        plot_w: WIDTH - LEFT - RIGHT,
    };
    let mut svg = String::with_capacity(1 << 20);
    map_frame(&mut svg, &frame, title, by.marks.len());
    let band_px = (job.tow.band_mm / frame.length_mm * frame.plot_w).clamp(0.4, 6.0);
    let mut passes_drawn = Vec::new();
    let mut turns_drawn = Vec::new();
    for (i, moves) in by.moves.iter().enumerate() {
        let start = by.starts[i].unwrap_or(Move {
            kind: MoveKind::Rapid,
            to: plan.start(),
            duration_s: 0.0,
        });
        let (np, nt) = layer_paths(
            &mut svg,
            &frame,
            moves,
            start,
            PALETTE[i % PALETTE.len()],
            band_px,
        );
        passes_drawn.push(np);
        turns_drawn.push(nt);
    }
    let thickness = thickness_profile(job, &by, start_mm, frame.length_mm);
    let top = TOP + MAP_H + GAP;
    thickness_panel(&mut svg, &frame, &thickness, top);
    legend(
        &mut svg,
        &by.marks,
        &passes_drawn,
        &turns_drawn,
        top + PROFILE_H + 30.0,
    );
    svg.push_str("</svg>\n");
    (
        svg,
        Layup {
            passes_drawn,
            turns_drawn,
            thickness,
        },
    )
}

/// The picture's opening, the title and the map's frame with its axes.
fn map_frame(svg: &mut String, frame: &MapFrame, title: &str, layers: usize) {
    let (start_mm, length, plot_w) = (frame.start_mm, frame.length_mm, frame.plot_w);
    let height = TOP + MAP_H + GAP + PROFILE_H + 40.0 + 18.0 * layers as f64;
    let _ = write!(
        svg,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{WIDTH}\" height=\"{height:.0}\" \
         viewBox=\"0 0 {WIDTH} {height:.0}\" font-family=\"sans-serif\" font-size=\"12\">\n\
         <rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n\
         <text x=\"{LEFT}\" y=\"20\" font-size=\"15\">{}: the mandrel unwrapped \
         (axial position from its start × mandrel angle), {layers} layers</text>\n\
         <rect x=\"{LEFT}\" y=\"{TOP}\" width=\"{plot_w}\" height=\"{MAP_H}\" fill=\"#f7f7f7\" \
         stroke=\"#444\"/>\n",
        escape(title),
    );
    for k in 0..=10 {
        let x = start_mm + length * k as f64 / 10.0;
        let _ = writeln!(
            svg,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{:.0}</text>",
            frame.sx(x),
            TOP + MAP_H + 15.0,
            x - start_mm
        );
    }
    for deg in [0.0, 90.0, 180.0, 270.0, 360.0] {
        let _ = writeln!(
            svg,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{deg:.0}°</text>",
            LEFT - 6.0,
            frame.sy(deg) + 4.0
        );
    }
    let _ = writeln!(
        svg,
        "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">axial position from the mandrel's \
         start, mm</text>",
        LEFT + plot_w / 2.0,
        TOP + MAP_H + 32.0
    );
}

/// One layer's moves from `start`: the passes in `colour` at the band's width, the turnarounds
/// as grey marks. Returns the passes and the turnarounds drawn.
fn layer_paths(
    svg: &mut String,
    frame: &MapFrame,
    moves: &[Move],
    start: Move,
    colour: &str,
    band_px: f64,
) -> (usize, usize) {
    let mut path = String::with_capacity(moves.len() * 40);
    let mut turns = String::new();
    let mut prev = start;
    let (mut np, mut nt) = (0, 0);
    // A pass: carriage moves one way, until it reverses or the mandrel turns with the
    // carriage still.
    let mut way = 0.0f64;
    for m in moves {
        let (x0, a0) = (prev.to.carriage_mm, prev.to.mandrel_deg);
        let (x1, a1) = (m.to.carriage_mm, m.to.mandrel_deg);
        prev = *m;
        if m.kind == MoveKind::Rapid || (a1 == a0 && x1 == x0) {
            continue;
        }
        if (x1 - x0).abs() < 1e-9 {
            nt += 1;
            way = 0.0;
            for (p0, p1) in wrapped(a0, a1) {
                let _ = write!(
                    turns,
                    "M{:.1} {:.1}V{:.1}",
                    frame.sx(x0),
                    frame.sy(p0),
                    frame.sy(p1)
                );
            }
            continue;
        }
        if (x1 - x0).signum() != way {
            np += 1;
            way = (x1 - x0).signum();
        }
        for (p0, p1, f0, f1) in wrapped_with_fraction(a0, a1) {
            let xa = x0 + (x1 - x0) * f0;
            let xb = x0 + (x1 - x0) * f1;
            let _ = write!(
                path,
                "M{:.1} {:.1}L{:.1} {:.1}",
                frame.sx(xa),
                frame.sy(p0),
                frame.sx(xb),
                frame.sy(p1)
            );
        }
    }
    let _ = writeln!(
        svg,
        "<path d=\"{path}\" fill=\"none\" stroke=\"{colour}\" stroke-opacity=\"0.55\" \
         stroke-width=\"{band_px:.2}\"/>"
    );
    if !turns.is_empty() {
        let _ = writeln!(
            svg,
            "<path d=\"{turns}\" fill=\"none\" stroke=\"#555\" stroke-width=\"3\" \
             stroke-opacity=\"0.6\"/>"
        );
    }
    (np, nt)
}

/// The thickness profile below the map, its top edge at `top`.
fn thickness_panel(svg: &mut String, frame: &MapFrame, thickness: &[(f64, f64)], top: f64) {
    let (length, plot_w) = (frame.length_mm, frame.plot_w);
    let t_max = thickness
        .iter()
        .map(|p| p.1)
        .fold(0.0f64, f64::max)
        .max(1e-6);
    let _ = writeln!(
        svg,
        "<rect x=\"{LEFT}\" y=\"{top}\" width=\"{plot_w}\" height=\"{PROFILE_H}\" fill=\"none\" \
         stroke=\"#444\"/>\n<text x=\"{LEFT}\" y=\"{:.1}\">laminate thickness along the mandrel, \
         mm (max {t_max:.3})</text>",
        top - 6.0
    );
    let mut line = String::new();
    for (k, &(x, t)) in thickness.iter().enumerate() {
        let px = LEFT + x / length * plot_w;
        let py = top + PROFILE_H - t / t_max * (PROFILE_H - 10.0);
        let _ = write!(line, "{}{px:.1} {py:.1}", if k == 0 { "M" } else { "L" });
    }
    let _ = writeln!(
        svg,
        "<path d=\"{line}\" fill=\"none\" stroke=\"#000\" stroke-width=\"1.5\"/>"
    );
    for frac in [0.0, 0.5, 1.0] {
        let _ = writeln!(
            svg,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{:.2}</text>",
            LEFT - 6.0,
            top + PROFILE_H - frac * (PROFILE_H - 10.0) + 4.0,
            t_max * frac
        );
    }
}

/// One line a layer, from `y` down: its colour, kind, angle, circuits, passes, turnarounds and
/// tow.
fn legend(svg: &mut String, marks: &[LayerMark], passes: &[usize], turns: &[usize], mut y: f64) {
    for (i, mark) in marks.iter().enumerate() {
        let kind = match mark.kind {
            LayerKind::Hoop => "hoop",
            LayerKind::Helical => "helical",
            LayerKind::Skip => "skip",
            LayerKind::Polar => "polar",
        };
        let _ = writeln!(
            svg,
            "<rect x=\"{LEFT}\" y=\"{:.1}\" width=\"24\" height=\"8\" fill=\"{}\"/>\
             <text x=\"{:.1}\" y=\"{:.1}\">layer {} {kind}: {:.3}°, {} circuits, {} passes, {} \
             turnarounds, tow {:.1} m</text>",
            y - 8.0,
            PALETTE[i % PALETTE.len()],
            LEFT + 32.0,
            y,
            mark.number,
            mark.wind_angle_deg,
            mark.circuits,
            passes[i],
            turns[i],
            mark.tow_length_mm / 1000.0
        );
        y += 18.0;
    }
}

/// Pieces of a mandrel turn from `a0` to `a1` (degrees, unwrapped) within 0…360°.
fn wrapped(a0: f64, a1: f64) -> Vec<(f64, f64)> {
    wrapped_with_fraction(a0, a1)
        .into_iter()
        .map(|(p0, p1, _, _)| (p0, p1))
        .collect()
}

/// Pieces of a move from `a0` to `a1` within 0…360°, with the fractions of the move where each
/// begins and ends.
fn wrapped_with_fraction(a0: f64, a1: f64) -> Vec<(f64, f64, f64, f64)> {
    let span = a1 - a0;
    if span == 0.0 {
        let p = a0.rem_euclid(360.0);
        return vec![(p, p, 0.0, 1.0)];
    }
    let mut pieces = Vec::new();
    let (lo, hi) = (a0.min(a1), a0.max(a1));
    let mut k = (lo / 360.0).floor();
    while k * 360.0 < hi {
        let s = lo.max(k * 360.0);
        let e = hi.min((k + 1.0) * 360.0);
        if e > s {
            let (fs, fe) = ((s - a0) / span, (e - a0) / span);
            let (ps, pe) = (s - k * 360.0, e - k * 360.0);
            if span > 0.0 {
                pieces.push((ps, pe, fs, fe));
            } else {
                pieces.push((pe, ps, fe, fs));
            }
        }
        k += 1.0;
    }
    if span < 0.0 {
        pieces.reverse();
    }
    pieces
}

fn thickness_profile(job: &Job, by: &ByLayer, start_mm: f64, length: f64) -> Vec<(f64, f64)> {
    let dx = length / STATIONS as f64;
    let xs: Vec<f64> = (0..=STATIONS).map(|k| k as f64 * dx).collect();
    let mut t = vec![0.0; xs.len()];
    let ply = job.tow.thickness_mm;
    if let Mandrel::Vessel {
        cylinder_radius_mm,
        cylinder_length_mm,
        polar_radius_mm,
    } = job.mandrel
    {
        let dome = (cylinder_radius_mm.powi(2) - polar_radius_mm.powi(2))
            .max(0.0)
            .sqrt();
        for mark in &by.marks {
            for (k, &x) in xs.iter().enumerate() {
                let z = if x < dome {
                    dome - x
                } else if x > dome + cylinder_length_mm {
                    x - dome - cylinder_length_mm
                } else {
                    0.0
                };
                t[k] += match mark.kind {
                    LayerKind::Helical | LayerKind::Polar => {
                        2.0 * ply
                            * paths::pattern::dome_thickness_ratio(
                                z,
                                cylinder_radius_mm,
                                polar_radius_mm,
                                job.tow.band_mm,
                            )
                    }
                    LayerKind::Hoop if z == 0.0 => ply,
                    _ => 0.0,
                };
            }
        }
        return xs.into_iter().zip(t).collect();
    }
    // Tubes, cones, noses: the tow laid over each station, by conservation of volume.
    let b = job.tow.band_mm;
    let mut prev: Option<Move> = None;
    for moves in &by.moves {
        for m in moves {
            let Some(p) = prev.replace(*m) else { continue };
            if m.kind == MoveKind::Rapid {
                continue;
            }
            let (x0, x1) = (p.to.carriage_mm - start_mm, m.to.carriage_mm - start_mm);
            if (x1 - x0).abs() < 1e-9 {
                continue;
            }
            let (lo, hi) = (x0.min(x1), x0.max(x1));
            let first = (lo / dx).ceil().max(0.0) as usize;
            let last = ((hi / dx).floor() as usize).min(STATIONS);
            if first > last {
                continue;
            }
            let turn = (m.to.mandrel_deg - p.to.mandrel_deg).to_radians();
            for k in first..=last {
                let x = xs[k];
                let r = radius_at(&job.mandrel, x);
                if r <= 1e-6 {
                    continue;
                }
                let slope = (radius_at(&job.mandrel, (x + 0.5).min(length))
                    - radius_at(&job.mandrel, (x - 0.5).max(0.0)))
                    / ((x + 0.5).min(length) - (x - 0.5).max(0.0));
                let dm_dx = (1.0 + slope * slope).sqrt();
                let dtheta_dx = turn / (x1 - x0);
                let dl_dm = (dm_dx * dm_dx + (r * dtheta_dx).powi(2)).sqrt() / dm_dx;
                t[k] += ply * b * dl_dm / (2.0 * std::f64::consts::PI * r);
            }
        }
    }
    xs.into_iter().zip(t).collect()
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_turn_is_cut_where_it_wraps() {
        let p = wrapped_with_fraction(350.0, 370.0);
        assert_eq!(p, [(350.0, 360.0, 0.0, 0.5), (0.0, 10.0, 0.5, 1.0)]);
        let p = wrapped_with_fraction(10.0, -10.0);
        assert_eq!(p, [(10.0, 0.0, 0.0, 0.5), (360.0, 350.0, 0.5, 1.0)]);
        assert_eq!(wrapped(0.0, 720.0).len(), 2);
    }

    #[test]
    fn the_ogive_radius_is_the_haack_series() {
        let m = Mandrel::VonKarman {
            base_radius_mm: 49.0,
            length_mm: 300.0,
        };
        assert!((radius_at(&m, 0.0) - 49.0).abs() < 1e-9);
        assert!(radius_at(&m, 300.0).abs() < 1e-9);
        // Half-way: φ = π/2, r = R·√(1/2).
        assert!((radius_at(&m, 150.0) - 49.0 * 0.5f64.sqrt()).abs() < 1e-9);
    }
}
