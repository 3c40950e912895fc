//! One motion representation for lathe winders: absolute axis targets, each a feed move with its
//! nominal duration or a true rapid, grouped into layers. Planners push it into a
//! [`MotionSink`]; G-code dialects are written from it and read back into it; the time estimate
//! runs over it.
//!
//! Machine frame of a lathe winder (seed 002 §3.1.2): the mandrel angle (degrees, unwrapped: it
//! only grows over a program), the carriage along the mandrel axis (mm, from the mandrel's
//! middle), the cross-feed (mm, the eye's distance from the mandrel axis) and the eye rotation
//! (degrees, 0 = roller axis along the mandrel axis).

use serde::Serialize;

/// Which axes a machine has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum AxisSet {
    /// Mandrel and carriage (the 2-axis fallback: the eye at a fixed distance, no rotation).
    Two,
    /// Mandrel, carriage and cross-feed (seed 000's A, X, Y).
    Three,
    /// Mandrel, carriage, cross-feed and eye rotation (seed 002's X, Y, Z, A).
    Four,
}

impl AxisSet {
    /// Whether the machine has a cross-feed axis.
    pub fn cross_feed(self) -> bool {
        self != AxisSet::Two
    }

    /// Whether the machine has an eye-rotation axis.
    pub fn eye_rotation(self) -> bool {
        self == AxisSet::Four
    }
}

/// Axis positions in the machine frame.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Axes {
    /// Mandrel angle, degrees, unwrapped.
    pub mandrel_deg: f64,
    /// Carriage position along the mandrel axis, mm.
    pub carriage_mm: f64,
    /// Eye distance from the mandrel axis, mm.
    pub cross_feed_mm: f64,
    /// Eye rotation, degrees.
    pub eye_deg: f64,
}

impl Axes {
    /// The four values in axis order (mandrel, carriage, cross-feed, eye).
    pub fn to_array(self) -> [f64; 4] {
        [
            self.mandrel_deg,
            self.carriage_mm,
            self.cross_feed_mm,
            self.eye_deg,
        ]
    }

    /// From the four values in axis order.
    pub fn from_array(a: [f64; 4]) -> Axes {
        Axes {
            mandrel_deg: a[0],
            carriage_mm: a[1],
            cross_feed_mm: a[2],
            eye_deg: a[3],
        }
    }
}

/// Feed or rapid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum MoveKind {
    /// Coordinated linear feed move (G1): the tow is being laid or tensioned.
    Feed,
    /// Positioning at the machine's rapid rate (G0): no tow under control.
    Rapid,
}

/// One straight move in axis space to an absolute target.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Move {
    /// Feed or rapid.
    pub kind: MoveKind,
    /// The absolute target.
    pub to: Axes,
    /// The nominal duration at the axes' velocity limits (the commanded feed), seconds; 0 for
    /// rapids (the controller's rate applies).
    pub duration_s: f64,
}

/// What a layer is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum LayerKind {
    /// Circumferential winding, one band per turn.
    Hoop,
    /// Helical winding (geodesic over the domes, or at a set angle on a tube).
    Helical,
    /// A mandrel turn with no tow laid.
    Skip,
    /// Polar (planar) winding over both openings of a vessel.
    Polar,
}

/// The start of a layer: a boundary where a stream may pause.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LayerMark {
    /// 1-based layer number.
    pub number: usize,
    /// What it is.
    pub kind: LayerKind,
    /// Circuits (out-and-back cycles) in the layer.
    pub circuits: u64,
    /// Tow laid on the mandrel in the layer, mm.
    pub tow_length_mm: f64,
    /// The winding radius of the layer (mandrel plus laminate below), mm.
    pub winding_radius_mm: f64,
    /// The cylinder wind angle of the layer, degrees.
    pub wind_angle_deg: f64,
}

/// Receives a plan as it is made, so a plan of any size streams with bounded memory.
pub trait MotionSink {
    /// The sink's error (I/O for writers).
    type Error;
    /// A layer begins; its moves follow.
    fn layer(&mut self, mark: &LayerMark) -> Result<(), Self::Error>;
    /// One move.
    fn motion(&mut self, m: &Move) -> Result<(), Self::Error>;
}

/// Collects everything in memory (tests, round trips, small plans).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Recording {
    /// The layer marks in order.
    pub layers: Vec<LayerMark>,
    /// The moves in order.
    pub moves: Vec<Move>,
    /// For each layer, the index of its first move.
    pub layer_starts: Vec<usize>,
}

impl MotionSink for Recording {
    type Error = std::convert::Infallible;
    fn layer(&mut self, mark: &LayerMark) -> Result<(), Self::Error> {
        self.layers.push(*mark);
        self.layer_starts.push(self.moves.len());
        Ok(())
    }
    fn motion(&mut self, m: &Move) -> Result<(), Self::Error> {
        self.moves.push(*m);
        Ok(())
    }
}

/// One axis's limits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AxisLimit {
    /// Maximum velocity, axis units per second.
    pub velocity: f64,
    /// Maximum acceleration, axis units per second squared.
    pub acceleration: f64,
}

/// Velocity and acceleration limits of the four axes (mandrel °/s, carriage mm/s, cross-feed mm/s,
/// eye °/s) and the cornering tolerance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Limits {
    /// Per axis, in axis order.
    pub axes: [AxisLimit; 4],
    /// How far a corner may be cut when it is taken without stopping (the GRBL-class planner's
    /// junction deviation), axis units.
    pub junction_deviation: f64,
}

impl Limits {
    /// The nominal duration of a straight move by `delta` (axis units): the slowest axis at its
    /// velocity limit.
    pub fn duration_s(&self, delta: [f64; 4]) -> f64 {
        delta
            .iter()
            .zip(&self.axes)
            .map(|(d, l)| d.abs() / l.velocity)
            .fold(0.0, f64::max)
    }
}

/// The planner buffer of the time estimate: like a GRBL-class controller, the estimate looks at
/// least this many moves ahead (and holds at most twice as many).
pub const LOOKAHEAD_MOVES: usize = 128;

#[derive(Debug, Clone, Copy)]
struct Planned {
    length: f64,
    unit: [f64; 4],
    nominal_speed: f64,
    acceleration: f64,
    max_entry: f64,
    entry: f64,
}

/// Summary of a plan: counts, tow length and the time a GRBL-class motion planner takes to run it
/// (trapezoidal velocity per move at the axes' velocity and acceleration limits, corners taken at
/// the junction-deviation speed, [`LOOKAHEAD_MOVES`] of look-ahead).
#[derive(Debug, Clone)]
pub struct Estimate {
    limits: Limits,
    inv_velocity: [f64; 4],
    inv_acceleration: [f64; 4],
    last: Axes,
    buffer: std::collections::VecDeque<Planned>,
    /// Layers seen.
    pub layers: usize,
    /// Circuits over all layers.
    pub circuits: u64,
    /// Moves seen.
    pub moves: u64,
    /// Tow laid, mm.
    pub tow_length_mm: f64,
    time_s: f64,
}

impl Estimate {
    /// An estimate starting at `start` with the machine's `limits`.
    pub fn new(limits: Limits, start: Axes) -> Estimate {
        Estimate {
            limits,
            inv_velocity: limits.axes.map(|l| 1.0 / l.velocity),
            inv_acceleration: limits.axes.map(|l| 1.0 / l.acceleration),
            last: start,
            buffer: std::collections::VecDeque::with_capacity(2 * LOOKAHEAD_MOVES),
            layers: 0,
            circuits: 0,
            moves: 0,
            tow_length_mm: 0.0,
            time_s: 0.0,
        }
    }

    /// The time to run everything seen, ending at rest, seconds.
    pub fn time_s(&self) -> f64 {
        let mut copy = self.buffer.clone();
        let mut t = self.time_s;
        Self::replan(&mut copy);
        for i in 0..copy.len() {
            let exit = copy.get(i + 1).map_or(0.0, |n| n.entry);
            t += trapezoid_time(&copy[i], exit);
        }
        t
    }

    /// Backward then forward pass over the buffer, the last move ending at rest.
    fn replan(buffer: &mut std::collections::VecDeque<Planned>) {
        let n = buffer.len();
        if n == 0 {
            return;
        }
        // Backward: each entry no faster than can still brake to the next entry.
        let mut next_entry = 0.0f64;
        for i in (1..n).rev() {
            let b = &mut buffer[i];
            let reachable = (next_entry * next_entry + 2.0 * b.acceleration * b.length).sqrt();
            b.entry = b.max_entry.min(reachable);
            next_entry = b.entry;
        }
        // Forward: the first entry is fixed; each entry no faster than the previous can reach.
        for i in 1..n {
            let prev = buffer[i - 1];
            let reachable =
                (prev.entry * prev.entry + 2.0 * prev.acceleration * prev.length).sqrt();
            let b = &mut buffer[i];
            b.entry = b.entry.min(reachable);
        }
    }

    fn push(&mut self, delta: [f64; 4]) {
        let length = delta.iter().map(|d| d * d).sum::<f64>().sqrt();
        if length <= 0.0 {
            return;
        }
        let inv_length = 1.0 / length;
        let unit = delta.map(|d| d * inv_length);
        // Path speed and acceleration at which the most limited axis is at its limit.
        let mut time_per_v = 0.0f64;
        let mut time_per_a = 0.0f64;
        for ((d, iv), ia) in delta
            .iter()
            .zip(&self.inv_velocity)
            .zip(&self.inv_acceleration)
        {
            time_per_v = time_per_v.max(d.abs() * iv);
            time_per_a = time_per_a.max(d.abs() * ia);
        }
        let speed = length / time_per_v;
        let acc = length / time_per_a;
        let max_entry = match self.buffer.back() {
            None => 0.0,
            Some(prev) => {
                // Junction deviation (GRBL): v² = a·δ·sin(θ/2)/(1 − sin(θ/2)), θ the angle
                // between the directions' reverse.
                let cos_theta = -prev.unit.iter().zip(&unit).map(|(a, b)| a * b).sum::<f64>();
                let v = if cos_theta > 0.999_999 {
                    0.0
                } else if cos_theta < -0.999_999 {
                    f64::INFINITY
                } else {
                    let sin_half = ((1.0 - cos_theta) / 2.0).sqrt();
                    (acc.min(prev.acceleration) * self.limits.junction_deviation * sin_half
                        / (1.0 - sin_half))
                        .sqrt()
                };
                v.min(speed).min(prev.nominal_speed)
            }
        };
        self.buffer.push_back(Planned {
            length,
            unit,
            nominal_speed: speed,
            acceleration: acc,
            max_entry,
            entry: max_entry,
        });
        // Plan in batches: with 2·N moves held, the first N are final (each still sees at least
        // N moves ahead of it), so replanning costs O(1) per move.
        if self.buffer.len() >= 2 * LOOKAHEAD_MOVES {
            Self::replan(&mut self.buffer);
            for _ in 0..LOOKAHEAD_MOVES {
                let first = self.buffer.pop_front().expect("buffer holds 2·N moves");
                let exit = self.buffer.front().map_or(0.0, |n| n.entry);
                self.time_s += trapezoid_time(&first, exit);
            }
        }
    }
}

/// Time of one move entering at `p.entry` and leaving at `exit`, cruising at most at its nominal
/// speed, accelerating at its limit.
fn trapezoid_time(p: &Planned, exit: f64) -> f64 {
    let (a, l, v0, v1) = (p.acceleration, p.length, p.entry, exit);
    let vc = p.nominal_speed;
    // Distance to accelerate to vc and to brake from it.
    let d_acc = (vc * vc - v0 * v0).max(0.0) / (2.0 * a);
    let d_dec = (vc * vc - v1 * v1).max(0.0) / (2.0 * a);
    if d_acc + d_dec <= l {
        (vc - v0) / a + (vc - v1) / a + (l - d_acc - d_dec) / vc
    } else {
        // Triangle: peak speed where both ramps meet.
        let vp = ((2.0 * a * l + v0 * v0 + v1 * v1) / 2.0).sqrt();
        (vp - v0).max(0.0) / a + (vp - v1).max(0.0) / a
    }
}

impl MotionSink for Estimate {
    type Error = std::convert::Infallible;
    fn layer(&mut self, mark: &LayerMark) -> Result<(), Self::Error> {
        self.layers += 1;
        self.circuits += mark.circuits;
        self.tow_length_mm += mark.tow_length_mm;
        Ok(())
    }
    fn motion(&mut self, m: &Move) -> Result<(), Self::Error> {
        let a = m.to.to_array();
        let b = self.last.to_array();
        let delta = [a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]];
        self.push(delta);
        self.last = m.to;
        self.moves += 1;
        Ok(())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    /// Every axis at 100 units/s and 1000 units/s², a junction deviation of 0.01: the limits the
    /// planner's tests run on.
    pub(crate) fn limits() -> Limits {
        let l = AxisLimit {
            velocity: 100.0,
            acceleration: 1000.0,
        };
        Limits {
            axes: [l; 4],
            junction_deviation: 0.01,
        }
    }

    fn feed(to: Axes) -> Move {
        Move {
            kind: MoveKind::Feed,
            to,
            duration_s: 0.0,
        }
    }

    #[test]
    fn one_long_move_is_a_trapezoid() {
        // 100 mm at 100 mm/s, 1000 mm/s²: 0.1 s up and 0.1 s down (5 mm each), 90 mm cruise
        // (0.9 s): L/v + v/a = 1.1 s.
        let mut e = Estimate::new(limits(), Axes::default());
        e.motion(&feed(Axes {
            carriage_mm: 100.0,
            ..Axes::default()
        }))
        .unwrap();
        assert_abs_diff_eq!(e.time_s(), 1.1, epsilon = 1e-12);
    }

    #[test]
    fn short_move_is_a_triangle() {
        // 1 mm: peak √(a·l) = 31.6 mm/s, time 2·√(l/a).
        let mut e = Estimate::new(limits(), Axes::default());
        e.motion(&feed(Axes {
            carriage_mm: 1.0,
            ..Axes::default()
        }))
        .unwrap();
        assert_abs_diff_eq!(e.time_s(), 2.0 * (1.0f64 / 1000.0).sqrt(), epsilon = 1e-12);
    }

    #[test]
    fn collinear_pieces_take_the_time_of_one_move_and_a_reversal_stops() {
        let mut split = Estimate::new(limits(), Axes::default());
        for i in 1..=400 {
            split
                .motion(&feed(Axes {
                    carriage_mm: f64::from(i) * 0.25,
                    ..Axes::default()
                }))
                .unwrap();
        }
        assert_abs_diff_eq!(split.time_s(), 1.1, epsilon = 1e-9);
        // Out and back: two full stops.
        let mut back = Estimate::new(limits(), Axes::default());
        back.motion(&feed(Axes {
            carriage_mm: 100.0,
            ..Axes::default()
        }))
        .unwrap();
        back.motion(&feed(Axes::default())).unwrap();
        assert_abs_diff_eq!(back.time_s(), 2.2, epsilon = 1e-9);
    }

    #[test]
    fn a_right_angle_corner_slows_but_does_not_stop() {
        let mut e = Estimate::new(limits(), Axes::default());
        e.motion(&feed(Axes {
            carriage_mm: 100.0,
            ..Axes::default()
        }))
        .unwrap();
        e.motion(&feed(Axes {
            carriage_mm: 100.0,
            mandrel_deg: 100.0,
            ..Axes::default()
        }))
        .unwrap();
        let t = e.time_s();
        assert!(t > 2.0 && t < 2.2, "{t}");
    }

    #[test]
    fn duration_is_the_slowest_axis() {
        let mut l = limits();
        l.axes[0].velocity = 360.0;
        assert_abs_diff_eq!(l.duration_s([720.0, 50.0, 0.0, 0.0]), 2.0, epsilon = 1e-12);
        assert_abs_diff_eq!(l.duration_s([-36.0, 300.0, 0.0, 0.0]), 3.0, epsilon = 1e-12);
    }
}
