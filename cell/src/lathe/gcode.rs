//! Lathe winding plans to G-code: a checked [`paths::vessel::Plan`] streamed through a
//! [`sequences::gcode::Writer`] and the time estimate in one pass, with the summary
//! `windcell lathe plan` prints.

use std::io::Write;

use paths::motion::{AxisSet, Estimate, LayerMark, MotionSink, Move};
use paths::pattern::Pattern;
use paths::vessel::Plan;
use sequences::gcode::{Dialect, Frame, Header, Writer};
use serde::Serialize;

/// What a written plan amounts to.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// The dialect written.
    pub dialect: &'static str,
    /// Layers.
    pub layers: usize,
    /// Circuits over all layers.
    pub circuits: u64,
    /// Moves.
    pub moves: u64,
    /// Lines of G-code.
    pub lines: u64,
    /// Tow laid on the mandrel, mm.
    pub tow_length_mm: f64,
    /// Time with the axes' velocity and acceleration limits and look-ahead, seconds.
    pub time_s: f64,
    /// Sum of the moves' velocity-limited durations (no acceleration), seconds.
    pub nominal_time_s: f64,
    /// Per layer.
    pub layer: Vec<LayerSummary>,
}

/// One layer of the summary.
#[derive(Debug, Clone, Serialize)]
pub struct LayerSummary {
    /// The planner's mark.
    #[serde(flatten)]
    pub mark: LayerMark,
    /// The helical pattern (seed 002 Eqs. 1–9), for dome layers.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pattern: Option<Pattern>,
}

struct Tee<'a, W: Write> {
    writer: &'a mut Writer<W>,
    estimate: &'a mut Estimate,
    nominal_s: f64,
}

impl<W: Write> MotionSink for Tee<'_, W> {
    type Error = std::io::Error;
    fn layer(&mut self, mark: &LayerMark) -> std::io::Result<()> {
        let _ = self.estimate.layer(mark);
        self.writer.layer(mark)
    }
    fn motion(&mut self, m: &Move) -> std::io::Result<()> {
        let _ = self.estimate.motion(m);
        self.nominal_s += m.duration_s;
        self.writer.motion(m)
    }
}

/// Writes `plan` as `dialect` G-code to `out` and sums it up. Fails only if the dialect lacks an
/// axis the machine uses ([`sequences::Error`]) or the output fails (as content errors).
pub fn write_program<W: Write>(
    plan: &Plan,
    axes: AxisSet,
    dialect: Dialect,
    title: &str,
    out: W,
) -> Result<(Summary, W), sequences::Error> {
    let writer = Writer::new(
        out,
        dialect,
        axes,
        &Header {
            title: title.to_string(),
            parameters: None,
        },
    )?;
    write_with(plan, dialect, writer)
}

/// Writes `plan` as `dialect` G-code in a machine's `frame` (its letters, origin, units and feed,
/// [`sequences::gcode::Frame::of_machine`]); the plan must have been checked against the
/// machine ([`sequences::machine::MachineProfile::admits`]).
pub fn write_in_frame<W: Write>(
    plan: &Plan,
    axes: AxisSet,
    dialect: Dialect,
    frame: Frame,
    header: &Header,
    out: W,
) -> Result<(Summary, W), sequences::Error> {
    let used = [true, true, axes.cross_feed(), axes.eye_rotation()];
    let writer = Writer::in_frame(out, dialect, frame, used, header)?;
    write_with(plan, dialect, writer)
}

fn write_with<W: Write>(
    plan: &Plan,
    dialect: Dialect,
    mut writer: Writer<W>,
) -> Result<(Summary, W), sequences::Error> {
    let mut estimate = Estimate::new(plan.limits(), plan.start());
    let mut tee = Tee {
        writer: &mut writer,
        estimate: &mut estimate,
        nominal_s: 0.0,
    };
    let io = |e: std::io::Error| sequences::Error::content(format!("writing the program: {e}"));
    plan.emit(&mut tee).map_err(io)?;
    let nominal_time_s = tee.nominal_s;
    let (out, lines) = writer.finish().map_err(io)?;
    Ok((
        Summary {
            dialect: dialect.name(),
            layers: estimate.layers,
            circuits: estimate.circuits,
            moves: estimate.moves,
            lines,
            tow_length_mm: estimate.tow_length_mm,
            time_s: estimate.time_s(),
            nominal_time_s,
            layer: plan
                .layers
                .iter()
                .map(|l| LayerSummary {
                    mark: l.mark,
                    pattern: l.pattern,
                })
                .collect(),
        },
        out,
    ))
}

/// Seconds as `h:mm:ss`.
pub fn clock(seconds: f64) -> String {
    let s = seconds.round() as u64;
    format!("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
}
