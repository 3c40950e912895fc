//! The lathe winder (seed 000): part program → absolute targets → trajectory per fibre circuit →
//! PD-controlled servo axes, with the run's figures (following error, peak velocity, acceleration
//! and jerk, completion time) and the actual-path trace of §9.9.
//!
//! Axis order is A (mandrel, degrees), X (carriage, mm), Y (cross-feed, mm), as in the part
//! program; inside, everything is encoder counts from machine zero. The part zero (seed 003 §4.2)
//! is an offset from machine zero; a program may carry it as a comment `(PART ZERO X… Y… A…)` in
//! its main program's first block.

pub mod gcode;
pub mod layup_scene;
pub mod layup_svg;
pub mod stream_watch;
pub mod trace_plot;

use std::path::{Path, PathBuf};

use mandrel_drive::lathe::{Controller, InterruptClock, LoopConfig};
use mandrel_drive::servo::{
    Amplifier, AxisIo, DAC_MAX_CODE, DAC_ZERO_CODE, LatheAxis, SimulatedAxes,
};
use nalgebra::{SVector, Vector3};
use paths::control::Pd;
use paths::limits::fixed;
use paths::trajectory::{AxisLimits, Interpolation, Planner, Trajectory, peaks};
use sequences::part_program::{Location, MachineParameters, PartProgram, Position, Step};

use crate::Error;
use crate::error::LatheSetting;

/// The machine and the run's settings.
#[derive(Debug, Clone, PartialEq)]
pub struct Setup {
    /// Interpolation for every run of moves.
    pub interpolation: Interpolation,
    /// Feed rate: the fastest axis's counts per interrupt.
    pub feed: f64,
    /// FW-CNC.PAR.
    pub params: MachineParameters,
    /// Interrupts per second.
    pub interrupt_hz: f64,
    /// Servo amplifier (same on every axis, App. C calibration).
    pub amplifier: Amplifier,
    /// PD gains (K_p, K_d); the velocity feed-forward is derived from the plant unless `kff` is
    /// given.
    pub kp: f64,
    /// K_d.
    pub kd: f64,
    /// Velocity feed-forward (None: the plant's, [`LoopConfig::feed_forward`]; 0: the thesis's
    /// plain PD).
    pub kff: Option<f64>,
    /// Acceleration limit of every axis, counts per interrupt² (point-to-point and blends).
    pub max_acceleration: f64,
    /// X and Y travel from machine zero to the high limit switch, mm.
    pub travel_mm: [f64; 2],
    /// Part zero: offset from machine zero (A deg, X mm, Y mm).
    pub part_zero: Position,
    /// Single-block execution (seed 003 §4.2 "step-by-step"): every block is its own
    /// point-to-point run, so the machine stops on each.
    pub single_block: bool,
    /// The 16-bit encoder counters' power-on value on every axis (seed 003 §4.1: the hardware
    /// counter starts anywhere and wraps from 65 535 to 0; the controller accumulates across).
    pub counter_start: u16,
}

impl Default for Setup {
    fn default() -> Self {
        Setup {
            interpolation: Interpolation::Linear,
            feed: 30.0,
            params: MachineParameters::default(),
            interrupt_hz: 200.0,
            amplifier: Amplifier::Voltage { k_amp: 0.45 },
            kp: Pd::THESIS.kp,
            kd: Pd::THESIS.kd,
            kff: None,
            max_acceleration: 4.0,
            travel_mm: [1000.0, 200.0],
            part_zero: Position {
                a_deg: 0.0,
                x_mm: 150.0,
                y_mm: 10.0,
            },
            single_block: false,
            counter_start: 0,
        }
    }
}

impl Setup {
    /// The controller's loop settings.
    pub fn loop_config(&self) -> LoopConfig {
        let kff = self.kff.unwrap_or_else(|| {
            LoopConfig::feed_forward(self.interrupt_hz, self.amplifier.plant(), self.kd)
        });
        LoopConfig {
            interrupt_hz: self.interrupt_hz,
            pd: Pd {
                kp: self.kp,
                kd: self.kd,
                kff,
            },
            polarity_guard: true,
        }
    }

    /// Counts from machine zero to axis units (A deg, X mm, Y mm) from part zero.
    pub fn from_counts(&self, counts_from_machine_zero: [f64; 3]) -> [f64; 3] {
        let zero = counts(&Position::default(), &self.part_zero);
        std::array::from_fn(|i| {
            (counts_from_machine_zero[i] - zero[i]) / LatheAxis::ALL[i].counts_per_unit()
        })
    }

    /// The fastest an axis can turn, encoder counts per interrupt: the plant's steady velocity
    /// `K·u/p` with the DAC at its full positive output (`u` = 2047 codes above 0 V), over the
    /// interrupt rate. With the thesis's voltage amplifier at K_amp 0.45 and 200 Hz, 174.8.
    pub fn top_speed_counts_per_interrupt(&self) -> f64 {
        let (gain, pole) = self.amplifier.plant();
        let full = f64::from(DAC_MAX_CODE - DAC_ZERO_CODE);
        gain * full / pole / self.interrupt_hz
    }

    fn planner(&self) -> Planner<3> {
        Planner::new(
            self.interrupt_hz,
            self.feed,
            AxisLimits {
                max_velocity: f64::MAX,
                max_acceleration: self.max_acceleration,
            },
        )
    }
}

/// A run of moves planned as one trajectory: one fibre circuit, or the main program's own moves
/// between stops.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// The planned trajectory (counts from machine zero).
    pub trajectory: Trajectory<3>,
    /// The circuit number (0-based) or `None` for main-program moves.
    pub circuit: Option<usize>,
    /// The block of every given point after the first.
    pub blocks: Vec<Location>,
    /// An M00 follows this run.
    pub stop_after: bool,
}

/// A planned part program.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The runs in order.
    pub runs: Vec<Run>,
    /// Fibre circuits.
    pub circuits: usize,
}

/// Reads the `(PART ZERO X… Y… A…)` comment of the main program's first block, if any.
pub fn part_zero_of(program: &PartProgram) -> Option<Position> {
    let main = program.main().ok()?;
    let comment = main.blocks.first()?.comment.as_deref()?;
    let rest = comment
        .trim()
        .strip_prefix("PART ZERO")
        .or_else(|| comment.trim().strip_prefix("part zero"))?;
    let mut p = Position::default();
    let words: Vec<&str> = rest.split_whitespace().collect();
    for pair in words.chunks(2) {
        let [letter, value] = pair else { return None };
        let v: f64 = value.parse().ok()?;
        match *letter {
            "A" | "a" => p.a_deg = v,
            "X" | "x" => p.x_mm = v,
            "Y" | "y" => p.y_mm = v,
            _ => return None,
        }
    }
    Some(p)
}

fn counts(p: &Position, zero: &Position) -> Vector3<f64> {
    Vector3::new(
        (p.a_deg + zero.a_deg) * LatheAxis::A.counts_per_unit(),
        (p.x_mm + zero.x_mm) * LatheAxis::X.counts_per_unit(),
        (p.y_mm + zero.y_mm) * LatheAxis::Y.counts_per_unit(),
    )
}

/// Expands and plans `program` (from `file`, for error messages): every target is checked against
/// the travel before anything is planned, so a move beyond a limit switch is refused with its
/// block's `FILE:LINE:COL`.
pub fn plan(program: &PartProgram, file: &Path, setup: &Setup) -> Result<Plan, Error> {
    let at_file = |e: sequences::Error| Error::File(e.in_file(file));
    let expanded = program.expand().map_err(at_file)?;
    let zero = setup.part_zero;
    for t in expanded.targets() {
        let x = t.position.x_mm + zero.x_mm;
        let y = t.position.y_mm + zero.y_mm;
        for (axis, v, travel) in [('X', x, setup.travel_mm[0]), ('Y', y, setup.travel_mm[1])] {
            if !(0.0..=travel).contains(&v) {
                return Err(at_file(t.at.error(format!(
                    "{axis} would reach {} mm from machine zero, beyond the limit switches \
                     (0 … {travel} mm; part zero {axis} {} mm)",
                    fixed(v, 2),
                    fixed(if axis == 'X' { zero.x_mm } else { zero.y_mm }, 2)
                ))));
            }
        }
    }
    // A feed the axes cannot reach would be planned and then not followed: refused.
    let top = setup.top_speed_counts_per_interrupt();
    if !(0.0..=top).contains(&setup.feed) {
        let (gain, pole) = setup.amplifier.plant();
        return Err(Error::LatheSetting(LatheSetting::FeedAboveTopSpeed {
            feed_counts_per_interrupt: setup.feed,
            top_counts_per_interrupt: top,
            plant_gain: gain,
            pole_per_s: pole,
            interrupt_hz: setup.interrupt_hz,
        }));
    }
    let planner = setup.planner();
    let interpolation = if setup.single_block {
        Interpolation::PointToPoint
    } else {
        setup.interpolation
    };
    let mut runs = Vec::new();
    let mut points = vec![counts(&expanded.start, &zero)];
    let mut blocks = Vec::new();
    let mut circuit = None;
    let mut flush = |points: &mut Vec<Vector3<f64>>,
                     blocks: &mut Vec<Location>,
                     circuit: Option<usize>,
                     stop_after: bool|
     -> Result<(), Error> {
        if points.len() >= 2 {
            let trajectory = planner
                .plan(points, interpolation)
                .map_err(|source| Error::Plan {
                    file: file.to_path_buf(),
                    line: blocks.first().map_or(1, |b: &Location| b.line),
                    column: blocks.first().map_or(1, |b: &Location| b.column),
                    source,
                })?;
            runs.push(Run {
                trajectory,
                circuit,
                blocks: std::mem::take(blocks),
                stop_after,
            });
        } else if stop_after && let Some(last) = runs.last_mut() {
            last.stop_after = true;
        }
        let last = points[points.len() - 1];
        points.clear();
        points.push(last);
        blocks.clear();
        Ok(())
    };
    for step in &expanded.steps {
        match step {
            Step::Move(t) => {
                if t.circuit != circuit && !blocks.is_empty() {
                    flush(&mut points, &mut blocks, circuit, false)?;
                }
                circuit = t.circuit;
                points.push(counts(&t.position, &zero));
                blocks.push(t.at);
                if setup.single_block {
                    flush(&mut points, &mut blocks, circuit, false)?;
                }
            }
            Step::Stop(_) => flush(&mut points, &mut blocks, circuit, true)?,
        }
    }
    flush(&mut points, &mut blocks, circuit, false)?;
    Ok(Plan {
        runs,
        circuits: expanded.circuits,
    })
}

/// One row of the actual-path trace (§9.9), in axis units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceRow {
    /// Interrupt number from the start.
    pub interrupt: u64,
    /// Machine time, s.
    pub time_s: f64,
    /// Desired A, X, Y from part zero.
    pub desired: [f64; 3],
    /// Measured A, X, Y from part zero.
    pub actual: [f64; 3],
}

/// One axis's figures, in its units (deg or mm, per s).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct AxisFigures {
    /// Axis letter.
    pub axis: char,
    /// Unit of the position figures.
    pub unit: &'static str,
    /// Largest |desired − measured|.
    pub max_following_error: f64,
    /// RMS of desired − measured.
    pub rms_following_error: f64,
    /// Peak measured speed, unit/s.
    pub peak_velocity: f64,
    /// Peak measured acceleration, unit/s².
    pub peak_acceleration: f64,
    /// Peak measured jerk, unit/s³.
    pub peak_jerk: f64,
    /// Peak planned speed, unit/s.
    pub planned_peak_velocity: f64,
    /// Interrupts with the DAC saturated.
    pub saturated_interrupts: u64,
}

/// A run's figures.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Report {
    /// Per axis: A, X, Y.
    pub axes: Vec<AxisFigures>,
    /// Interrupts executed.
    pub interrupts: u64,
    /// Machine time to completion, s.
    pub completion_time_s: f64,
    /// Fibre circuits wound.
    pub circuits: usize,
    /// Program stops (M00) passed.
    pub stops: usize,
    /// The run before which the progress hook stopped the program (the axes at rest at the end
    /// of the run before), if it did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub halted_before_run: Option<usize>,
}

/// Progress events while running.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Progress {
    /// A circuit finished (0-based number, of `total`).
    Circuit {
        /// The circuit just finished.
        done: usize,
        /// Circuits in the program.
        total: usize,
    },
    /// An M00 was reached.
    Stop,
    /// A run (one trajectory) is about to start (single-block hook): the hook's
    /// [`ControlFlow::Break`](std::ops::ControlFlow::Break) stops the program there, the axes
    /// at rest.
    RunStart {
        /// Index of the run.
        run: usize,
    },
}

/// Running statistics of one axis.
#[derive(Debug, Clone, Copy, Default)]
struct AxisStats {
    max_err: f64,
    sum_sq: f64,
    saturated: u64,
}

/// Sees every interrupt: its number, the desired and the measured positions (counts from machine
/// zero).
pub type TickHook<'a> = &'a mut dyn FnMut(u64, &[f64; 3], &[i64; 3]);

/// Runs `plan` on `controller` paced by `clock`. The controller's origin must be machine zero.
/// `trace_every` > 0 records a [`TraceRow`] every that many interrupts into `trace`;
/// `on_progress` sees circuits and stops, and may stop the program before a run;
/// `on_tick` sees every interrupt (desired and measured
/// counts from machine zero, for a recorder).
#[allow(clippy::too_many_arguments, clippy::needless_range_loop)]
pub fn execute<I: AxisIo>(
    plan: &Plan,
    setup: &Setup,
    controller: &mut Controller<I>,
    clock: &mut dyn InterruptClock,
    trace_every: u64,
    trace: &mut Vec<TraceRow>,
    on_progress: &mut dyn FnMut(Progress) -> std::ops::ControlFlow<()>,
    on_tick: TickHook<'_>,
) -> Result<Report, Error> {
    let scale: [f64; 3] = LatheAxis::ALL.map(|a| a.counts_per_unit());
    let zero = counts(&Position::default(), &setup.part_zero);
    let mut stats = [AxisStats::default(); 3];
    let mut planned_peak = [0.0f64; 3];
    let mut k: u64 = 0;
    let mut stops = 0usize;
    let hz = setup.interrupt_hz;
    // Peaks of the measured motion, from a sliding window of four samples.
    let mut window: Vec<SVector<f64, 3>> = Vec::with_capacity(4);
    let mut peak_v = [0.0f64; 3];
    let mut peak_a = [0.0f64; 3];
    let mut peak_j = [0.0f64; 3];
    let transfer = |e: mandrel_drive::Error| Error::Lathe { source: e };
    let mut halted_before_run = None;
    for (r, run) in plan.runs.iter().enumerate() {
        if on_progress(Progress::RunStart { run: r }).is_break() {
            halted_before_run = Some(r);
            break;
        }
        let p = run.trajectory.peaks();
        for i in 0..3 {
            planned_peak[i] = planned_peak[i].max(p.velocity[i]);
        }
        let sp = &run.trajectory.setpoints;
        // Hold the last setpoint a little after each run so the axes settle (tripled end).
        let settle = (hz * 0.05) as usize;
        for n in 1..sp.len() + settle {
            let d = sp[n.min(sp.len() - 1)];
            let prev = sp[(n - 1).min(sp.len() - 1)];
            let v = d - prev;
            clock.wait();
            let tick = controller
                .tick([d[0], d[1], d[2]], [v[0], v[1], v[2]])
                .map_err(transfer)?;
            let period = controller.period_s();
            controller.io_mut().elapse(period);
            k += 1;
            let pos = tick.position;
            on_tick(k, &[d[0], d[1], d[2]], &pos);
            let m = SVector::<f64, 3>::new(pos[0] as f64, pos[1] as f64, pos[2] as f64);
            for i in 0..3 {
                let e = d[i] - m[i];
                stats[i].max_err = stats[i].max_err.max(e.abs());
                stats[i].sum_sq += e * e;
                if tick.saturated[i] {
                    stats[i].saturated += 1;
                }
            }
            if window.len() == 4 {
                window.remove(0);
            }
            window.push(m);
            let pk = peaks(&window, hz);
            for i in 0..3 {
                peak_v[i] = peak_v[i].max(pk.velocity[i]);
                peak_a[i] = peak_a[i].max(pk.acceleration[i]);
                peak_j[i] = peak_j[i].max(pk.jerk[i]);
            }
            if trace_every > 0 && k.is_multiple_of(trace_every) {
                trace.push(TraceRow {
                    interrupt: k,
                    time_s: k as f64 / hz,
                    desired: std::array::from_fn(|i| (d[i] - zero[i]) / scale[i]),
                    actual: std::array::from_fn(|i| (m[i] - zero[i]) / scale[i]),
                });
            }
        }
        if let Some(c) = run.circuit {
            let last_of_circuit = plan.runs.get(r + 1).is_none_or(|n| n.circuit != Some(c));
            if last_of_circuit {
                let _ = on_progress(Progress::Circuit {
                    done: c,
                    total: plan.circuits,
                });
            }
        }
        if run.stop_after {
            stops += 1;
            let _ = on_progress(Progress::Stop);
        }
    }
    controller.stop();
    let n = k.max(1) as f64;
    let axes = LatheAxis::ALL
        .iter()
        .enumerate()
        .map(|(i, a)| AxisFigures {
            axis: a.letter(),
            unit: a.unit(),
            max_following_error: stats[i].max_err / scale[i],
            rms_following_error: (stats[i].sum_sq / n).sqrt() / scale[i],
            peak_velocity: peak_v[i] / scale[i],
            peak_acceleration: peak_a[i] / scale[i],
            peak_jerk: peak_j[i] / scale[i],
            planned_peak_velocity: planned_peak[i] / scale[i],
            saturated_interrupts: stats[i].saturated,
        })
        .collect();
    Ok(Report {
        axes,
        interrupts: k,
        completion_time_s: k as f64 / hz,
        circuits: plan.circuits,
        stops,
        halted_before_run,
    })
}

/// Plans and runs `program` on the simulated machine in simulated time, starting at part zero.
pub fn simulate(
    program: &PartProgram,
    file: &Path,
    setup: &Setup,
    trace_every: u64,
) -> Result<(Report, Vec<TraceRow>), Error> {
    let plan = plan(program, file, setup)?;
    let mut controller = start_at_part_zero(setup)?;
    let mut trace = Vec::new();
    let report = execute(
        &plan,
        setup,
        &mut controller,
        &mut mandrel_drive::lathe::SimulatedClock,
        trace_every,
        &mut trace,
        &mut |_| std::ops::ControlFlow::Continue(()),
        &mut |_, _, _| {},
    )?;
    Ok((report, trace))
}

/// A controller over the simulated machine with the axes standing at part zero (machine zero is
/// the controller's origin).
pub fn start_at_part_zero(setup: &Setup) -> Result<Controller<SimulatedAxes>, Error> {
    let transfer = |e: mandrel_drive::Error| Error::Lathe { source: e };
    let zero = counts(&Position::default(), &setup.part_zero);
    let amp = setup.amplifier;
    let x = LatheAxis::X.counts_per_unit();
    let y = LatheAxis::Y.counts_per_unit();
    let machine = SimulatedAxes::new(vec![
        mandrel_drive::servo::ServoAxis::new(amp)
            .map_err(transfer)?
            .with_counter(setup.counter_start)
            .at(zero[0]),
        mandrel_drive::servo::ServoAxis::new(amp)
            .map_err(transfer)?
            .with_switches(-5.0 * x, setup.travel_mm[0] * x)
            .with_home(-x)
            .with_counter(setup.counter_start)
            .at(zero[1]),
        mandrel_drive::servo::ServoAxis::new(amp)
            .map_err(transfer)?
            .with_switches(-5.0 * y, setup.travel_mm[1] * y)
            .with_home(-y)
            .with_counter(setup.counter_start)
            .at(zero[2]),
    ]);
    let mut controller = Controller::new(machine, setup.loop_config()).map_err(transfer)?;
    // The counters started at power-on with the axes at part zero: make machine zero the origin.
    controller.shift_origin([
        -(zero[0].round() as i64),
        -(zero[1].round() as i64),
        -(zero[2].round() as i64),
    ]);
    Ok(controller)
}

/// One axis's machine-zero search on the simulated machine.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Homed {
    /// Axis letter.
    pub axis: char,
    /// Where the axis stood at power-on, mm from the home switch's frame (the switch is made
    /// at −1 mm, the low limit switch at −5 mm).
    pub start_mm: f64,
    /// Interrupts the search took.
    pub interrupts: u64,
    /// The shaft's encoder count where the search left the axis (machine zero), counted from
    /// the simulator's fixed frame: the same from any start.
    pub machine_zero_count: i64,
    /// The 16-bit hardware counter there.
    pub raw_counter: u16,
}

/// Machine-zero search (seed 003 §4.2) of X and Y on the simulated machine, starting at `start_mm`
/// (X, Y): toward the home switch at 20 counts per interrupt, off it at 0.25, then `backoff`
/// whole encoder pulses beyond the release edge. A start outside the limit switches is refused.
pub fn home(setup: &Setup, start_mm: [f64; 2], backoff: i64) -> Result<Vec<Homed>, Error> {
    let transfer = |e: mandrel_drive::Error| Error::Lathe { source: e };
    for (i, (&s, travel)) in start_mm.iter().zip(setup.travel_mm).enumerate() {
        if !(s > -5.0 && s < travel) {
            return Err(Error::LatheSetting(LatheSetting::HomeStart {
                axis: ['X', 'Y'][i],
                start_mm: s,
                travel_mm: travel,
            }));
        }
    }
    if !(0..=4000).contains(&backoff) {
        return Err(Error::LatheSetting(LatheSetting::HomeBackoff {
            pulses: backoff,
        }));
    }
    let amp = setup.amplifier;
    let x = LatheAxis::X.counts_per_unit();
    let y = LatheAxis::Y.counts_per_unit();
    let axis = |scale: f64, travel: f64, start: f64| -> Result<_, Error> {
        Ok(mandrel_drive::servo::ServoAxis::new(amp)
            .map_err(transfer)?
            .with_switches(-5.0 * scale, travel * scale)
            .with_home(-scale)
            .with_counter(setup.counter_start)
            .at(start * scale))
    };
    let machine = SimulatedAxes::new(vec![
        mandrel_drive::servo::ServoAxis::new(amp)
            .map_err(transfer)?
            .with_counter(setup.counter_start),
        axis(x, setup.travel_mm[0], start_mm[0])?,
        axis(y, setup.travel_mm[1], start_mm[1])?,
    ]);
    let mut controller = Controller::new(machine, setup.loop_config()).map_err(transfer)?;
    let mut out = Vec::new();
    for (i, scale) in [(1usize, x), (2, y)] {
        let max_travel = ((setup.travel_mm[i - 1] + 10.0) * scale).ceil() as i64;
        let interrupts = controller
            .home(
                i,
                20.0,
                0.25,
                backoff,
                max_travel,
                &mut mandrel_drive::lathe::SimulatedClock,
            )
            .map_err(transfer)?;
        let shaft = &controller.io().axes[i];
        out.push(Homed {
            axis: LatheAxis::ALL[i].letter(),
            start_mm: start_mm[i - 1],
            interrupts,
            machine_zero_count: shaft.position().floor() as i64,
            raw_counter: shaft.counter(),
        });
    }
    Ok(out)
}

/// An electronically geared run's figures.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Geared {
    /// Carriage millimetres per mandrel degree.
    pub ratio_mm_per_deg: f64,
    /// Interrupts run.
    pub interrupts: u64,
    /// Mandrel angle reached, degrees from part zero.
    pub mandrel_deg: f64,
    /// Carriage position reached, mm from part zero.
    pub carriage_mm: f64,
    /// Largest |X − ratio · A| during the run, mm.
    pub worst_error_mm: f64,
}

/// Electronic gearing (seed 003 §4.1 item 3) instead of interpolated axes: the mandrel (master)
/// turns `turns` at `speed_deg_s`, reaching it in `ramp_s` and stopping the same way; the
/// carriage (slave) follows the mandrel's measured angle at `ratio_mm_per_deg` from part zero.
/// The carriage's whole travel is checked against the limit switches first.
pub fn gear(
    setup: &Setup,
    ratio_mm_per_deg: f64,
    speed_deg_s: f64,
    turns: f64,
    ramp_s: f64,
) -> Result<Geared, Error> {
    let bad = |setting| Err(Error::LatheSetting(setting));
    if !ratio_mm_per_deg.is_finite() {
        return bad(LatheSetting::GearRatio { ratio_mm_per_deg });
    }
    if !(speed_deg_s > 0.0 && speed_deg_s <= 3600.0) {
        return bad(LatheSetting::GearSpeed { speed_deg_s });
    }
    if !(turns > 0.0 && turns <= 1000.0) {
        return bad(LatheSetting::GearTurns { turns });
    }
    if !(0.0..=60.0).contains(&ramp_s) {
        return bad(LatheSetting::GearRamp { ramp_s });
    }
    let angle_deg = turns * 360.0;
    if angle_deg / speed_deg_s + ramp_s > 3600.0 {
        return bad(LatheSetting::GearTooLong {
            angle_deg,
            speed_deg_s,
        });
    }
    let end_x = setup.part_zero.x_mm + ratio_mm_per_deg * angle_deg;
    if !(0.0..=setup.travel_mm[0]).contains(&end_x) {
        return bad(LatheSetting::CarriageBeyondLimits {
            end_mm: end_x,
            travel_mm: setup.travel_mm[0],
            ratio_mm_per_deg,
            angle_deg,
        });
    }
    // The master's profile: trapezoidal in speed (a triangle when the turns are few).
    let hz = setup.interrupt_hz;
    let a_scale = LatheAxis::A.counts_per_unit();
    let total = angle_deg * a_scale;
    let v_max = speed_deg_s * a_scale / hz;
    let ramp_n = (ramp_s * hz).max(1.0);
    let accel = v_max / ramp_n;
    let mut master = Vec::new();
    let (mut p, mut v) = (0.0f64, 0.0f64);
    while p < total {
        let braking = v * v / (2.0 * accel);
        v = if total - p <= braking {
            (v - accel).max(accel.min(total - p))
        } else {
            (v + accel).min(v_max)
        };
        p = (p + v).min(total);
        master.push(p);
    }
    let transfer = |e: mandrel_drive::Error| Error::Lathe { source: e };
    let mut controller = start_at_part_zero(setup)?;
    // Gear about part zero: the part zero is the controller's origin during the geared run.
    let zero = counts(&Position::default(), &setup.part_zero);
    controller.shift_origin([
        zero[0].round() as i64,
        zero[1].round() as i64,
        zero[2].round() as i64,
    ]);
    let ratio_counts = ratio_mm_per_deg * LatheAxis::X.counts_per_unit() / a_scale;
    // Hold the end a little so the slave settles.
    let hold = (hz * 0.2) as usize;
    master.extend(std::iter::repeat_n(total, hold));
    let worst = mandrel_drive::lathe::run_geared(
        &mut controller,
        &master,
        ratio_counts,
        &mut mandrel_drive::lathe::SimulatedClock,
    )
    .map_err(transfer)?;
    controller.stop();
    let pos = controller.position();
    Ok(Geared {
        ratio_mm_per_deg,
        interrupts: master.len() as u64,
        mandrel_deg: pos[0] as f64 / a_scale,
        carriage_mm: pos[1] as f64 / LatheAxis::X.counts_per_unit(),
        worst_error_mm: worst / LatheAxis::X.counts_per_unit(),
    })
}

/// Writes the trace as CSV (all or nothing: written beside the target and renamed).
pub fn write_trace(path: &Path, rows: &[TraceRow]) -> Result<(), Error> {
    let mut text = String::from(
        "interrupt,time_s,desired_a_deg,desired_x_mm,desired_y_mm,actual_a_deg,actual_x_mm,actual_y_mm\n",
    );
    for r in rows {
        text.push_str(&format!(
            "{},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}\n",
            r.interrupt,
            r.time_s,
            r.desired[0],
            r.desired[1],
            r.desired[2],
            r.actual[0],
            r.actual[1],
            r.actual[2]
        ));
    }
    let mut staging = path.as_os_str().to_owned();
    staging.push(".partial");
    let staging = PathBuf::from(staging);
    std::fs::write(&staging, text)
        .and_then(|()| std::fs::rename(&staging, path))
        .map_err(|source| Error::Output {
            path: path.to_path_buf(),
            source,
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    const FIG_9_1: &str = include_str!("../../../examples/cone-dome-cylinder.prg");

    fn fig_9_1() -> PartProgram {
        PartProgram::parse(FIG_9_1).unwrap()
    }

    fn one_circuit() -> PartProgram {
        PartProgram::parse(&FIG_9_1.replace("L 3", "L 1")).unwrap()
    }

    fn setup(interpolation: Interpolation, feed: f64) -> Setup {
        Setup {
            interpolation,
            feed,
            ..Setup::default()
        }
    }

    const BSPLINE: Interpolation = Interpolation::BSpline {
        knots_per_segment: 4,
    };

    /// The top speed is the Ch. 7 plant's steady velocity at full DAC output: 1772 × 0.45 ×
    /// 2047 codes / 46.7 /s = 34 953 counts/s, 174.8 counts per interrupt at 200 Hz (and half
    /// that at 400 Hz). A feed at it plans; one count per interrupt above it is refused.
    #[test]
    fn a_feed_above_the_axes_top_speed_is_refused() {
        let s = setup(Interpolation::Linear, 30.0);
        let top = 1772.0 * 0.45 * 2047.0 / 46.7 / 200.0;
        assert!((s.top_speed_counts_per_interrupt() - top).abs() < 1e-9);
        let doubled = Setup {
            interrupt_hz: 400.0,
            ..s
        };
        assert!((doubled.top_speed_counts_per_interrupt() - top / 2.0).abs() < 1e-9);
        let f = Path::new("f.prg");
        assert!(plan(&fig_9_1(), f, &setup(Interpolation::Linear, top)).is_ok());
        for feed in [top + 1.0, 1e308, f64::INFINITY] {
            match plan(&fig_9_1(), f, &setup(Interpolation::Linear, feed)) {
                Err(e @ Error::LatheSetting(LatheSetting::FeedAboveTopSpeed { .. })) => {
                    assert!(e.is_input());
                    let message = e.to_string();
                    assert!(
                        message.contains("above the axes' top speed of 174.8"),
                        "{message}"
                    );
                }
                other => panic!("{feed}: {other:?}"),
            }
        }
    }

    #[test]
    fn fig_9_1_plans_three_circuits_of_113_knot_points() {
        let plan = plan(&fig_9_1(), Path::new("f.prg"), &setup(BSPLINE, 30.0)).unwrap();
        assert_eq!(plan.circuits, 3);
        assert_eq!(plan.runs.len(), 3);
        for (i, run) in plan.runs.iter().enumerate() {
            assert_eq!(run.circuit, Some(i));
            assert_eq!(run.trajectory.path.len(), 113);
            assert_eq!(run.blocks.len(), 26);
        }
        assert!(plan.runs[2].stop_after);
        // A circuit returns X and Y to where it started; A advances 480.98°.
        let first = plan.runs[0].trajectory.setpoints[0];
        let last = *plan.runs[0].trajectory.setpoints.last().unwrap();
        assert!((last[1] - first[1]).abs() < 1e-6 && (last[2] - first[2]).abs() < 1e-6);
        let a = (last[0] - first[0]) / LatheAxis::A.counts_per_unit();
        assert!((a - 480.98).abs() < 1e-6, "{a}");
    }

    #[test]
    fn bspline_has_lower_peak_acceleration_and_jerk_at_feed_80() {
        let (lin, _) = simulate(
            &fig_9_1(),
            Path::new("f.prg"),
            &setup(Interpolation::Linear, 80.0),
            0,
        )
        .unwrap();
        let (bs, _) = simulate(&fig_9_1(), Path::new("f.prg"), &setup(BSPLINE, 80.0), 0).unwrap();
        for axis in 0..3 {
            let (l, b) = (&lin.axes[axis], &bs.axes[axis]);
            assert!(
                b.peak_acceleration < l.peak_acceleration,
                "{axis}: {b:?} {l:?}"
            );
            assert!(b.peak_jerk < l.peak_jerk, "{axis}: {b:?} {l:?}");
            assert!(b.max_following_error < l.max_following_error);
        }
        assert_eq!(lin.circuits, 3);
        assert_eq!(bs.stops, 1);
    }

    /// The highest integer feed (counts per interrupt) at which X and Y stay within ±0.5 mm of
    /// the plan on one circuit of Fig 9-1 (§10.5's criterion).
    fn max_feed(interpolation: Interpolation) -> f64 {
        let ok = |feed: f64| {
            let (r, _) = simulate(
                &one_circuit(),
                Path::new("f.prg"),
                &setup(interpolation, feed),
                0,
            )
            .unwrap();
            r.axes[1].max_following_error <= 0.5 && r.axes[2].max_following_error <= 0.5
        };
        let (mut lo, mut hi) = (0.5f64, 160.0f64);
        assert!(!ok(hi));
        for _ in 0..10 {
            let mid = (lo + hi) / 2.0;
            if ok(mid) { lo = mid } else { hi = mid }
        }
        lo
    }

    #[test]
    fn bspline_winds_at_least_one_and_a_half_times_faster_within_half_a_millimetre() {
        let linear = max_feed(Interpolation::Linear);
        let bspline = max_feed(BSPLINE);
        assert!(linear > 1.0, "{linear}");
        assert!(
            bspline >= 1.5 * linear,
            "linear {linear}, b-spline {bspline}"
        );
    }

    #[test]
    fn a_move_beyond_a_limit_switch_is_refused_before_motion() {
        let mut s = setup(Interpolation::Linear, 30.0);
        s.part_zero.x_mm = 50.0;
        let e = plan(&fig_9_1(), Path::new("prg/f.prg"), &s).unwrap_err();
        assert!(e.is_input());
        // N30 takes X to −50.59 mm + … the first block that goes below machine zero is N75.
        let text = e.to_string();
        assert!(text.starts_with("prg/f.prg:"), "{text}");
        assert!(text.contains("beyond the limit switches"), "{text}");
        let line: usize = text.split(':').nth(1).unwrap().parse().unwrap();
        assert!(
            FIG_9_1.lines().nth(line - 1).unwrap().starts_with('N'),
            "{text}"
        );
        // Beyond the far end of Y.
        let mut s = setup(Interpolation::Linear, 30.0);
        s.travel_mm[1] = 60.0;
        let e = plan(&fig_9_1(), Path::new("f.prg"), &s)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("f.prg:9:1: Y would reach"), "{e}");
    }

    #[test]
    fn single_block_stops_on_every_block() {
        let mut s = setup(BSPLINE, 30.0);
        s.single_block = true;
        let plan = plan(&one_circuit(), Path::new("f.prg"), &s).unwrap();
        assert_eq!(plan.runs.len(), 26);
        for run in &plan.runs {
            assert_eq!(run.blocks.len(), 1);
            let sp = &run.trajectory.setpoints;
            assert_eq!(sp.last(), run.trajectory.points.last());
        }
        let mut starts = 0;
        let mut circuits = Vec::new();
        let mut c = start_at_part_zero(&s).unwrap();
        execute(
            &plan,
            &s,
            &mut c,
            &mut mandrel_drive::lathe::SimulatedClock,
            0,
            &mut Vec::new(),
            &mut |p| {
                match p {
                    Progress::RunStart { .. } => starts += 1,
                    Progress::Circuit { done, total } => circuits.push((done, total)),
                    Progress::Stop => {}
                }
                std::ops::ControlFlow::Continue(())
            },
            &mut |_, _, _| {},
        )
        .unwrap();
        assert_eq!(starts, 26);
        assert_eq!(circuits, [(0, 1)]);
    }

    #[test]
    fn bad_programs_name_the_file() {
        let p = PartProgram::parse("O 1; M98 P 5; M30;").unwrap();
        let e = plan(&p, Path::new("a.prg"), &Setup::default()).unwrap_err();
        assert_eq!(
            e.to_string(),
            "a.prg:1:6: M98 calls O5, which is not in the file"
        );
        assert!(e.is_input());
    }

    #[test]
    fn part_zero_comment() {
        let p = PartProgram::parse("O 1 (PART ZERO X 120.5 Y 4 A 0); G91 X 1; M30;").unwrap();
        assert_eq!(
            part_zero_of(&p),
            Some(Position {
                a_deg: 0.0,
                x_mm: 120.5,
                y_mm: 4.0
            })
        );
        assert_eq!(part_zero_of(&fig_9_1()), None);
        let bad = PartProgram::parse("O 1 (PART ZERO X); M30;").unwrap();
        assert_eq!(part_zero_of(&bad), None);
    }

    #[test]
    fn trace_rows_every_n_interrupts_and_csv() {
        let (r, trace) = simulate(
            &one_circuit(),
            Path::new("f.prg"),
            &setup(BSPLINE, 30.0),
            20,
        )
        .unwrap();
        assert_eq!(trace.len() as u64, r.interrupts / 20);
        assert_eq!(trace[0].interrupt, 20);
        let last = trace.last().unwrap();
        assert!((last.actual[1] - last.desired[1]).abs() < 0.5);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.csv");
        write_trace(&path, &trace).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text.lines().count(), trace.len() + 1);
        assert!(text.starts_with("interrupt,time_s,desired_a_deg"));
    }
}
