//! `windcell lathe run PROGRAM`: plan a part program (seed 000 Fig 9-1 format) and run it on the
//! simulated lathe winder's PD-controlled servo axes, in simulated time or paced by the wall
//! clock; report following error, peak velocity, acceleration and jerk and the completion time;
//! write the actual-path trace (§9.9) as CSV.

use std::io::BufRead;
use std::path::PathBuf;

use cell::lathe::{self, Progress, Setup, TraceRow};
use cell::record::{LatheAxes, Level, Recorder, Sinks};
use clap::{Args, ValueEnum};
use mandrel_drive::lathe::{InterruptClock, Jitter, SimulatedClock, WallClock};
use mandrel_drive::servo::{Amplifier, LatheAxis};
use paths::trajectory::{Interpolation, Remedy};
use sequences::part_program::{Location, MachineParameters, PartProgram, Position};
use serde_json::json;

use crate::cli::{Failure, print};

/// Interpolation choices on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum InterpArg {
    /// Constant velocity per block (§9.5).
    Linear,
    /// Uniform cubic B-spline, ends tripled (§9.6).
    Bspline,
    /// Stop on every point (§8.4 a).
    PointToPoint,
    /// Linear with parabolic blends (§8.5).
    Blend,
}

/// Interrupt pacing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ClockArg {
    /// Simulated time: as fast as the computer goes.
    Sim,
    /// The wall clock at the interrupt rate; jitter is measured and reported.
    Real,
}

/// Run a part program on the simulated lathe winder.
#[derive(Debug, Args)]
pub struct LatheRunArgs {
    /// The part program (.PRG).
    pub program: PathBuf,
    /// Interpolation.
    #[arg(long, value_enum, default_value_t = InterpArg::Linear)]
    pub interp: InterpArg,
    /// Feed rate: the fastest axis's encoder counts per interrupt (default: the parameter
    /// file's feed rate limit).
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    pub feed: Option<f64>,
    /// FW-CNC.PAR (default: the thesis's values 20, 10, 30, 20, 4).
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// Write the actual path every record-interval interrupts as CSV.
    #[arg(long, value_name = "FILE")]
    pub trace: Option<PathBuf>,
    /// Plot X desired, actual and following error over the run (SVG, every interrupt).
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
    /// Report as JSON on standard output.
    #[arg(long)]
    pub json: bool,
    /// Interrupt pacing.
    #[arg(long, value_enum, default_value_t = ClockArg::Sim)]
    pub clock: ClockArg,
    /// Interrupt rate, Hz (1 … 1000).
    #[arg(
        long,
        value_name = "HZ",
        default_value_t = 200.0,
        allow_negative_numbers = true
    )]
    pub rate: f64,
    /// With `--clock real`: busy-wait this long before each interrupt instead of sleeping
    /// (default 150 µs; a whole period or more never sleeps, at the cost of a core).
    #[arg(
        long,
        value_name = "MICROSECONDS",
        default_value_t = 150,
        allow_negative_numbers = true
    )]
    pub spin_us: u64,
    /// Servo amplifier gain K_amp (voltage amplifier, Ch. 7).
    #[arg(long, default_value_t = 0.45, allow_negative_numbers = true)]
    pub k_amp: f64,
    /// Part zero from machine zero as X_MM,Y_MM,A_DEG (default: the program's `(PART ZERO …)`
    /// comment, else 150,10,0).
    #[arg(long, value_name = "X,Y,A", allow_hyphen_values = true)]
    pub part_zero: Option<String>,
    /// Stop before every block and wait for Enter on standard input (seed 003 step-by-step).
    #[arg(long)]
    pub single_block: bool,
    /// Circuits per layer, for the layer counter of the progress display.
    #[arg(
        long,
        value_name = "N",
        default_value_t = 1,
        allow_negative_numbers = true
    )]
    pub circuits_per_layer: usize,
    /// Record the axes' commanded and actual positions and following error every interrupt
    /// (topic `/lathe/axes`) and the progress (`/log`) as MCAP for Foxglove.
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
    /// Power-on value of the 16-bit encoder counters (they wrap from 65 535 to 0; seed 003 §4.1).
    #[arg(
        long,
        value_name = "RAW",
        default_value_t = 0,
        allow_negative_numbers = true
    )]
    pub counter_start: u16,
}

fn parse_part_zero(text: &str) -> Result<Position, Failure> {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| Failure::input(format!("--part-zero: '{text}' is not X_MM,Y_MM,A_DEG")))?;
    match v.as_slice() {
        [x, y, a] if v.iter().all(|c| c.is_finite()) => Ok(Position {
            a_deg: *a,
            x_mm: *x,
            y_mm: *y,
        }),
        _ => Err(Failure::input(format!(
            "--part-zero: '{text}' is not X_MM,Y_MM,A_DEG"
        ))),
    }
}

/// Runs `windcell lathe run`: arguments → checks (the setup, the plan) → the run → the report.
pub fn run(args: LatheRunArgs) -> Result<(), Failure> {
    let program = PartProgram::load(&args.program).map_err(Failure::input)?;
    let setup = setup_of(&args, &program)?;
    let inputs: Vec<PathBuf> = std::iter::once(args.program.clone())
        .chain(args.params.iter().cloned())
        .collect();
    let outputs: Vec<&std::path::Path> = [&args.trace, &args.plot, &args.record]
        .into_iter()
        .flatten()
        .map(PathBuf::as_path)
        .collect();
    cell::plan::output::check_output_files(&outputs, &inputs).map_err(Failure::from_cell)?;
    // Everything that can be refused is refused here, before any motion.
    let plan = lathe::plan(&program, &args.program, &setup).map_err(Failure::from_cell)?;
    let mut controller = lathe::start_at_part_zero(&setup).map_err(Failure::from_cell)?;
    let deviations = deviations(&plan);
    let wound = wind(&args, &setup, &plan, &mut controller)?;
    write_trace_files(&args, &setup, &wound.trace)?;
    let report = Report {
        args: &args,
        setup: &setup,
        wound: &wound,
        deviations: &deviations,
    };
    if args.json {
        report.json()
    } else {
        report.text()
    }
}

/// The setup the arguments and the parameter file make, every argument checked.
fn setup_of(args: &LatheRunArgs, program: &PartProgram) -> Result<Setup, Failure> {
    let params = match &args.params {
        Some(p) => MachineParameters::load(p).map_err(Failure::input)?,
        None => MachineParameters::default(),
    };
    let feed = args.feed.unwrap_or(f64::from(params.feed_limit));
    if !(feed > 0.0 && feed.is_finite()) {
        return Err(Failure::input(format!(
            "--feed: {} must be > 0",
            paths::limits::shown(feed)
        )));
    }
    super::check_rate(args.rate)?;
    super::check_k_amp(args.k_amp)?;
    if args.circuits_per_layer == 0 {
        return Err(Failure::input("--circuits-per-layer: must be ≥ 1"));
    }
    let knots = params.knots_per_segment as usize;
    let interpolation = match args.interp {
        InterpArg::Linear => Interpolation::Linear,
        InterpArg::Bspline => Interpolation::BSpline {
            knots_per_segment: knots,
        },
        InterpArg::PointToPoint => Interpolation::PointToPoint,
        InterpArg::Blend => Interpolation::ParabolicBlend,
    };
    let mut setup = Setup {
        interpolation,
        feed,
        params,
        interrupt_hz: args.rate,
        amplifier: Amplifier::Voltage { k_amp: args.k_amp },
        single_block: args.single_block,
        counter_start: args.counter_start,
        ..Setup::default()
    };
    if let Some(z) = lathe::part_zero_of(program) {
        setup.part_zero = z;
    }
    if let Some(text) = &args.part_zero {
        setup.part_zero = parse_part_zero(text)?;
    }
    Ok(setup)
}

/// A given point the planned path passes farther than the tolerance from: the block, the offset
/// (A °, X mm, Y mm) and the remedies.
type Deviation = (Location, [f64; 3], Vec<Remedy>);

/// Deviation report: how far the planned path passes from each given point (0.5 mm or 0.5° on
/// every axis).
fn deviations(plan: &lathe::Plan) -> Vec<Deviation> {
    let tolerance = nalgebra::Vector3::new(
        0.5 * LatheAxis::A.counts_per_unit(),
        0.5 * LatheAxis::X.counts_per_unit(),
        0.5 * LatheAxis::Y.counts_per_unit(),
    );
    let mut deviations = Vec::new();
    for run in &plan.runs {
        for d in run.trajectory.deviations(&tolerance) {
            if d.exceeds && d.index > 0 {
                let at = run.blocks[d.index - 1];
                let offset: [f64; 3] =
                    std::array::from_fn(|i| d.offset[i] / LatheAxis::ALL[i].counts_per_unit());
                deviations.push((at, offset, d.remedies.clone()));
            }
        }
    }
    deviations
}

/// What a finished run leaves: the controller's report, the trace rows and, on the wall clock,
/// the interrupts' lateness.
struct Wound {
    report: lathe::Report,
    trace: Vec<TraceRow>,
    jitter: Option<Jitter>,
}

/// The MCAP recorder of `--record`, if asked for.
fn open_recorder(path: Option<&PathBuf>) -> Result<Option<Recorder>, Failure> {
    let Some(path) = path else {
        return Ok(None);
    };
    let epoch_ns = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    let sinks = Sinks {
        mcap: Some(path.clone()),
        live: None,
    };
    Recorder::open(&sinks, epoch_ns)
        .map(Some)
        .map_err(Failure::from_cell)
}

/// Runs the plan on the controller, paced by the chosen clock: progress on standard error (and
/// in the recording), Enter awaited before every block with `--single-block`.
fn wind(
    args: &LatheRunArgs,
    setup: &Setup,
    plan: &lathe::Plan,
    controller: &mut mandrel_drive::lathe::Controller<mandrel_drive::servo::SimulatedAxes>,
) -> Result<Wound, Failure> {
    let mut trace: Vec<TraceRow> = Vec::new();
    let every = if args.plot.is_some() {
        1
    } else if args.trace.is_some() {
        u64::from(setup.params.record_interval)
    } else {
        0
    };
    let mut sim_clock = SimulatedClock;
    let mut wall = match args.clock {
        ClockArg::Real => Some(
            WallClock::new(args.rate)
                .map_err(Failure::input)?
                .with_spin(std::time::Duration::from_micros(args.spin_us)),
        ),
        ClockArg::Sim => None,
    };
    let clock: &mut dyn InterruptClock = match wall.as_mut() {
        Some(w) => w,
        None => &mut sim_clock,
    };
    let recorder = open_recorder(args.record.as_ref())?;
    let hz = args.rate;
    let interrupts_done = std::cell::Cell::new(0u64);
    let mut on_tick = |k: u64, desired: &[f64; 3], measured: &[i64; 3]| {
        interrupts_done.set(k);
        if let Some(rec) = &recorder {
            let commanded = setup.from_counts(*desired);
            let actual = setup.from_counts(measured.map(|c| c as f64));
            rec.lathe_axes(k as f64 / hz, &LatheAxes::new(k, commanded, actual));
        }
    };
    let log = |message: &str| {
        if let Some(rec) = &recorder {
            rec.log(interrupts_done.get() as f64 / hz, Level::Info, message);
        }
    };
    let report = lathe::execute(
        plan,
        setup,
        controller,
        clock,
        every,
        &mut trace,
        &mut progress_display(args, plan, &log),
        &mut on_tick,
    )
    .map_err(Failure::from_cell)?;
    if let Some(rec) = recorder {
        rec.finish().map_err(Failure::from_cell)?;
    }
    if let Some(run) = report.halted_before_run {
        let at = plan.runs[run].blocks[0];
        return Err(Failure::runtime(format!(
            "{}:{}:{}: --single-block: standard input closed before this block; stopped with the \
             axes at rest ({run} of {} blocks run; each block waits for Enter)",
            args.program.display(),
            at.line,
            at.column,
            plan.runs.len()
        )));
    }
    Ok(Wound {
        report,
        trace,
        jitter: wall.as_ref().map(WallClock::jitter),
    })
}

/// The operator's view of the run: each circuit with its layer and each program stop on
/// standard error (not with `--json`) and to `log`; with `--single-block`, the block to run
/// next, waiting for Enter (end of input stops the program).
fn progress_display<'a>(
    args: &'a LatheRunArgs,
    plan: &'a lathe::Plan,
    log: &'a dyn Fn(&str),
) -> impl FnMut(Progress) -> std::ops::ControlFlow<()> + 'a {
    let quiet = args.json;
    let per_layer = args.circuits_per_layer;
    let single = args.single_block;
    let mut stdin = std::io::stdin().lock();
    move |p: Progress| {
        match p {
            Progress::Circuit { done, total } => {
                let text = format!(
                    "circuit {}/{total} wound, layer {} of {}",
                    done + 1,
                    done / per_layer + 1,
                    total.div_ceil(per_layer)
                );
                log(&text);
                if !quiet {
                    eprintln!("{text}");
                }
            }
            Progress::Stop => {
                log("M00 program stop");
                if !quiet {
                    eprintln!("M00 program stop");
                }
            }
            Progress::RunStart { run } => {
                if single {
                    let at = plan.runs[run].blocks[0];
                    eprint!(
                        "block {}:{}:{}: press Enter to run it ",
                        args.program.display(),
                        at.line,
                        at.column
                    );
                    let mut line = String::new();
                    // End of input (or an unreadable one) is not an Enter: stop here.
                    if !matches!(stdin.read_line(&mut line), Ok(n) if n > 0) {
                        eprintln!();
                        return std::ops::ControlFlow::Break(());
                    }
                }
            }
        }
        std::ops::ControlFlow::Continue(())
    }
}

/// `--plot` (every interrupt) and `--trace` (every record interval) files.
fn write_trace_files(
    args: &LatheRunArgs,
    setup: &Setup,
    trace: &[TraceRow],
) -> Result<(), Failure> {
    if let Some(path) = &args.plot {
        let title = format!(
            "{}: {:?}, feed {} counts/interrupt",
            args.program.display(),
            args.interp,
            setup.feed
        );
        cell::lathe::trace_plot::write_svg(path, trace, &title).map_err(Failure::from_cell)?;
    }
    if let Some(path) = &args.trace {
        let interval = u64::from(setup.params.record_interval);
        let rows: Vec<TraceRow> = trace
            .iter()
            .filter(|r| r.interrupt.is_multiple_of(interval))
            .copied()
            .collect();
        lathe::write_trace(path, &rows).map_err(Failure::from_cell)?;
    }
    Ok(())
}

fn interp_name(interp: InterpArg) -> &'static str {
    match interp {
        InterpArg::Linear => "linear",
        InterpArg::Bspline => "bspline",
        InterpArg::PointToPoint => "point-to-point",
        InterpArg::Blend => "blend",
    }
}

fn remedy_name(r: &Remedy) -> &'static str {
    match r {
        Remedy::TriplePoint => "triple the point",
        Remedy::InsertMidpoints => "insert the chord midpoints",
        Remedy::UseLinear => "use linear interpolation here",
    }
}

/// What the run reports on: its arguments and setup, what it wound, the deviations planned.
struct Report<'a> {
    args: &'a LatheRunArgs,
    setup: &'a Setup,
    wound: &'a Wound,
    deviations: &'a [Deviation],
}

impl Report<'_> {
    /// The `--json` report.
    fn json(&self) -> Result<(), Failure> {
        let report = &self.wound.report;
        let devs: Vec<_> = self
            .deviations
            .iter()
            .map(|(at, off, rem)| {
                json!({
                    "block": format!("{}:{}:{}", self.args.program.display(), at.line, at.column),
                    "offset": {"a_deg": off[0], "x_mm": off[1], "y_mm": off[2]},
                    "remedies": rem.iter().map(remedy_name).collect::<Vec<_>>(),
                })
            })
            .collect();
        let value = json!({
            "program": self.args.program.display().to_string(),
            "interpolation": interp_name(self.args.interp),
            "feed_counts_per_interrupt": self.setup.feed,
            "interrupt_hz": self.args.rate,
            "clock": if self.wound.jitter.is_some() { "real" } else { "sim" },
            "axes": report.axes,
            "interrupts": report.interrupts,
            "completion_time_s": report.completion_time_s,
            "circuits": report.circuits,
            "stops": report.stops,
            "deviations": devs,
            "jitter": self.wound.jitter.map(|j| json!({
                "interrupts": j.interrupts,
                "p50_us": j.p50_us,
                "p99_us": j.p99_us,
                "max_us": j.max_us,
                "missed": j.missed,
            })),
        });
        let text = serde_json::to_string_pretty(&value).map_err(Failure::runtime)?;
        print(&format!("{text}\n"))
    }

    /// The plain report: the axes' figures, the completion time, the worst deviation and the wall
    /// clock's lateness.
    fn text(&self) -> Result<(), Failure> {
        let report = &self.wound.report;
        let mut out = format!(
            "{}: {} circuit(s), {}, feed {} counts/interrupt at {} Hz\n",
            self.args.program.display(),
            report.circuits,
            interp_name(self.args.interp),
            self.setup.feed,
            self.args.rate
        );
        out.push_str("axis  max err     rms err     peak v/s     peak a/s²     peak j/s³\n");
        for a in &report.axes {
            out.push_str(&format!(
                "{}     {:>8.3}    {:>8.3}    {:>9.1}    {:>10.0}    {:>11.0}   ({})\n",
                a.axis,
                a.max_following_error,
                a.rms_following_error,
                a.peak_velocity,
                a.peak_acceleration,
                a.peak_jerk,
                a.unit
            ));
        }
        out.push_str(&format!(
            "completed in {:.2} s ({} interrupts)\n",
            report.completion_time_s, report.interrupts
        ));
        let largest = |o: &[f64; 3]| o.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if let Some(worst) = self
            .deviations
            .iter()
            .max_by(|a, b| largest(&a.1).total_cmp(&largest(&b.1)))
        {
            out.push_str(&format!(
                "deviation: the path passes more than 0.5 mm (or 0.5°) from {} given point(s); \
             worst {}:{}:{} (A {:.2}°, X {:.2} mm, Y {:.2} mm); remedies: {}\n",
                self.deviations.len(),
                self.args.program.display(),
                worst.0.line,
                worst.0.column,
                worst.1[0],
                worst.1[1],
                worst.1[2],
                worst
                    .2
                    .iter()
                    .map(remedy_name)
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
        if let Some(j) = self.wound.jitter {
            out.push_str(&format!(
            "wall clock: {} interrupts, lateness p50 {:.1} µs, p99 {:.1} µs, max {:.1} µs, {} missed\n",
            j.interrupts, j.p50_us, j.p99_us, j.max_us, j.missed
        ));
        }
        print(&out)
    }
}
