//! Control files to devices, end to end on the simulators: plan an example job in memory, convert
//! path 1 with `cell::run::transfer`, upload the robot program with verified stores over the simulated
//! 9600-baud link in virtual time, run it, and check the eye's path against the planned eye
//! positions; run the `.IND` move on the simulated X-language indexer and check steps and angle.

use std::path::{Path, PathBuf};
use std::time::Duration;

use asea_protocol::clock::VirtualClock;
use asea_protocol::command::INTERPRETATION_S;
use asea_protocol::command::LENGTH_MM_PER_LSB;
use asea_protocol::command::{IN_POSITION_OUTPUT, START_INPUT};
use asea_protocol::link::Paced;
use asea_protocol::sim::{MotionParams, Robot};
use asea_protocol::{Client, ClientConfig, Command, FrameConfig, Mode, State, Timers};
use cell::plan::tool::{JobPlan, PlannedPath};
use cell::run::transfer::{self, IndexerSetup};
use mandrel_drive::sim::machine::PULL_IN_SPS;
use mandrel_drive::sim::xlang::Card;
use mandrel_drive::sim::{Clock, Frontend, Machine};
use mandrel_drive::units::TRANSLATOR_LIMIT_PPS;
use mandrel_drive::{Drive, xlang};
use sequences::{Job, Movement, RobotFile};

/// Virtual-time step at which the eye's position is sampled while the program runs, s.
const SAMPLE_S: f64 = 0.0001;
/// Largest error of a telegram position: half an LSB on each axis.
const QUANTISATION_MM: f64 = LENGTH_MM_PER_LSB / 2.0 * 1.732_050_807_568_877_2;

fn planned(name: &str) -> (Job, JobPlan) {
    let file: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../examples")
        .join(format!("{name}.toml"));
    let (job, text) = Job::load(&file).unwrap();
    let plan = cell::plan::tool::plan(&job, &text, &file).unwrap();
    (job, plan)
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

type RobotLink = Client<Paced<Robot>, VirtualClock>;

/// A robot simulator on the paced wire, speeds set from the header, in OPERATE and homed.
fn robot_ready(rob: &RobotFile) -> RobotLink {
    let clock = VirtualClock::new();
    let robot = Robot::new(
        FrameConfig::default(),
        Timers::default(),
        MotionParams::default(),
    );
    let wire = Paced::new(clock.clone(), 9600, robot);
    let mut c = Client::with_clock(wire, clock, ClientConfig::default());
    let (base, max) = transfer::speeds(&rob.header).unwrap();
    c.send(&Command::SetBaseSpeed(base)).unwrap();
    c.send(&Command::SetMaxSpeed(max)).unwrap();
    c.operate().unwrap();
    c.sync_home().unwrap();
    c.link_mut().run_for(Duration::from_secs_f64(3.5));
    let s = c.check_status().unwrap();
    assert!(s.homed && s.mode == Mode::Operate, "{s:?}");
    c
}

/// What a stored-program run measured.
#[derive(Debug)]
struct ProgramRun {
    /// Per planned point: the closest approach of the sampled eye while the robot executed that
    /// instruction or the next, mm.
    closest_mm: Vec<f64>,
    /// Per planned point: the eye at the end of its instruction (`Machine::trace`), mm away.
    trace_mm: Vec<f64>,
    /// Largest distance between consecutive samples after the first, mm.
    sample_spacing_mm: f64,
    /// Virtual run time, s.
    run_s: f64,
    /// Seconds from the end of instruction 1 to the end of the last.
    winding_s: f64,
}

/// Uploads and runs `rob` (fine or medium) on the simulator; returns what the eye did.
fn run_program(rob: &RobotFile) -> ProgramRun {
    let prog = transfer::robot_program(rob).unwrap();
    let mut c = robot_ready(rob);
    let report = c.upload_verified(prog.program, &prog.instructions).unwrap();
    assert_eq!(report.checked, prog.instructions.len());
    let io = c.link().peer.machine.io().clone();
    assert!(!io.output(IN_POSITION_OUTPUT));
    let t0 = c.link().clock().now();
    c.run_program(prog.program).unwrap();
    // The program waits for the PC's start with "in position" low and the arm still.
    let at_start = c.link().peer.machine.pose().xyz_mm;
    c.link_mut().run_for(Duration::from_secs(2));
    assert!(!io.output(IN_POSITION_OUTPUT));
    assert_eq!(c.link().peer.machine.pose().xyz_mm, at_start);
    assert_eq!(
        c.link().peer.machine.status().instruction,
        transfer::PROLOGUE_LEN
    );
    io.set_input(START_INPUT, true);
    // (instruction under way, eye position) every SAMPLE_S of virtual time until the robot idles.
    let mut samples: Vec<(u16, [f64; 3])> = Vec::new();
    let mut sample_spacing_mm: f64 = 0.0;
    loop {
        let m = &c.link().peer.machine;
        let s = m.status();
        let pos = m.pose().xyz_mm;
        // The first interval is the RUN_PROGRAM session's tail, during which the arm already left
        // home; it lies on the approach to point 1, not at a planned point.
        if let Some((_, prev)) = samples.last().filter(|_| samples.len() > 1) {
            sample_spacing_mm = sample_spacing_mm.max(distance(*prev, pos));
        }
        samples.push((s.instruction.saturating_sub(transfer::PROLOGUE_LEN), pos));
        assert_ne!(s.state, State::Error, "robot stopped: {s:?}");
        // "In position" only once the last point is reached.
        let n = rob.instructions.len();
        assert!(
            !io.output(IN_POSITION_OUTPUT)
                || usize::from(s.instruction.saturating_sub(transfer::PROLOGUE_LEN)) > n,
            "in-position output raised during instruction {}",
            s.instruction
        );
        if s.state == State::Idle {
            break;
        }
        assert!(samples.len() < 10_000_000, "program never ended");
        c.link_mut().run_for(Duration::from_secs_f64(SAMPLE_S));
    }
    let run_s = (c.link().clock().now() - t0).as_secs_f64();
    assert!(
        io.output(IN_POSITION_OUTPUT),
        "in-position output not raised"
    );
    let status = c.check_status().unwrap();
    assert_eq!(status.state, State::Idle);

    let n = rob.instructions.len();
    let mut closest_mm = Vec::with_capacity(n);
    let mut last_index = 0;
    for (k, i) in rob.instructions.iter().enumerate() {
        let number = i.number;
        let window = samples.iter().enumerate().filter(|(_, (at, _))| {
            *at == number || *at == number + 1 || (k + 1 == n && *at > number)
        });
        let (index, d) = window
            .map(|(j, (_, p))| (j, distance(*p, i.position_mm)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or_else(|| panic!("instruction {number} never executed"));
        assert!(index >= last_index, "point {number} passed out of order");
        last_index = index;
        closest_mm.push(d);
    }
    let trace = &c.link().peer.machine.trace;
    assert_eq!(trace.len(), n);
    let trace_mm = trace
        .iter()
        .zip(&rob.instructions)
        .map(|((_, pose), i)| distance(pose.xyz_mm, i.position_mm))
        .collect();
    // From reaching point 1 (the end of the approach from home) to the end of the last point.
    let winding_s = trace.last().map_or(0.0, |t| t.0) - trace.first().map_or(0.0, |t| t.0);
    ProgramRun {
        closest_mm,
        trace_mm,
        sample_spacing_mm,
        run_s,
        winding_s,
    }
}

fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(0.0, f64::max)
}

fn check_program(name: &str, path: &PlannedPath, job: &Job, movement: Movement) -> f64 {
    let mut rob = cell::plan::tool::robot_file(job, path).unwrap();
    rob.header.movement = movement;
    let radius_mm = transfer::zone(movement).unwrap().radius_mm();
    let run = run_program(&rob);
    let worst = max(&run.closest_mm);
    eprintln!(
        "{name} {movement:?}: {} points, closest approach max {worst:.4} mm (zone {radius_mm} mm), \
         instruction-end pose max {:.4} mm, sample spacing {:.4} mm, run {:.1} s, winding {:.2} s \
         (plan {:.2} s)",
        run.closest_mm.len(),
        max(&run.trace_mm),
        run.sample_spacing_mm,
        run.run_s,
        run.winding_s,
        path.plan.segments.iter().map(|s| s.duration_s).sum::<f64>()
    );
    // From point 1 to the last point, each instruction takes the plan's time or the robot
    // computer's interpretation time of its zone, whichever is longer (App. B: fine windings
    // had to run slower than medium); the last point adds its stop, at most the overhead and
    // ramps of Table 6.2's fine plateau.
    let plan_s: f64 = path.plan.segments.iter().map(|s| s.duration_s).sum();
    let zone_index = usize::from(movement == Movement::Medium);
    let floor_s = INTERPRETATION_S[zone_index];
    let expected_s: f64 = path
        .plan
        .segments
        .iter()
        .skip(1)
        .map(|s| s.duration_s.max(floor_s))
        .sum();
    eprintln!(
        "{name} {movement:?}: winding {:.3} s, expected {expected_s:.3} s, plan {plan_s:.3} s, \
         segments under the interpretation time {}",
        run.winding_s,
        path.plan
            .segments
            .iter()
            .filter(|s| s.duration_s < floor_s)
            .count()
    );
    assert!(
        run.winding_s >= 0.98 * expected_s && run.winding_s <= 1.02 * expected_s + 0.71,
        "{name} {movement:?}: winding {} s, expected {expected_s} s",
        run.winding_s
    );
    // The closest sample overstates the closest approach by at most half the sample spacing, so
    // the check is never kinder than the path.
    for (k, d) in run.closest_mm.iter().enumerate() {
        assert!(
            *d <= radius_mm,
            "{name} {movement:?}: point {} missed by {d:.4} mm (zone {radius_mm} mm)",
            k + 1
        );
    }
    // The last point is a stop: reached to the telegram's resolution.
    assert!(run.closest_mm.last().copied().unwrap_or(f64::MAX) <= QUANTISATION_MM);
    worst
}

/// The example job `name`'s first path, in fine and in medium movement, through
/// [`check_program`].
fn path_1_runs_within_its_zones(name: &str) {
    let (job, plan) = planned(name);
    for movement in [Movement::Fine, Movement::Medium] {
        check_program(name, &plan.paths[0], &job, movement);
    }
}

#[test]
fn sbend_path_1_runs_on_the_simulated_robot_within_its_zones() {
    path_1_runs_within_its_zones("sbend");
}

#[test]
fn cylinder_path_1_runs_on_the_simulated_robot_within_its_zones() {
    path_1_runs_within_its_zones("cylinder");
}

#[test]
fn sbend_path_1_in_discrete_movement_stops_at_every_point() {
    let (job, plan) = planned("sbend");
    let rob = cell::plan::tool::robot_file(&job, &plan.paths[0]).unwrap();
    let moves = transfer::immediate_moves(&rob).unwrap();
    let mut c = robot_ready(&rob);
    let io = c.link().peer.machine.io().clone();
    let mut worst: f64 = 0.0;
    for (cmd, i) in moves.iter().zip(&rob.instructions) {
        c.send(cmd).unwrap();
        assert!(!io.output(IN_POSITION_OUTPUT));
        let mut waited = 0;
        while !io.output(IN_POSITION_OUTPUT) {
            c.link_mut().run_for(Duration::from_millis(10));
            waited += 1;
            assert!(
                waited < 100_000,
                "instruction {} never in position",
                i.number
            );
        }
        let d = distance(c.link().peer.machine.pose().xyz_mm, i.position_mm);
        worst = worst.max(d);
        assert!(d <= QUANTISATION_MM, "instruction {}: {d} mm", i.number);
    }
    eprintln!(
        "sbend Discrete: {} points, stop deviation max {worst:.4} mm",
        moves.len()
    );
}

/// Sends X-language commands to the simulated card, 10 ms of virtual time apart.
fn send_x(card: &mut Card, clock: &mandrel_drive::sim::VirtualClock, cmds: &[xlang::Command]) {
    for cmd in cmds {
        let line = format!("{}\r", xlang::encode(Some(1), cmd));
        card.receive(line.as_bytes(), clock.now_s());
        card.poll(clock.now_s());
        clock.advance_s(0.01);
    }
}

/// Sends one move's commands and lets virtual time run until its move-complete notification
/// (CR LF; the echoes end in CR only).
fn run_x_move(
    card: &mut Card,
    clock: &mandrel_drive::sim::VirtualClock,
    cmds: &[xlang::Command],
    what: &str,
) {
    card.take_output();
    send_x(card, clock, cmds);
    let mut out = card.take_output();
    let mut waited = 0;
    while !out.contains(&b'\n') {
        clock.advance_s(0.01);
        card.poll(clock.now_s());
        out.extend(card.take_output());
        waited += 1;
        assert!(
            waited < 1_000_000,
            "{what}: the mandrel move never completed"
        );
    }
    assert!(!out.contains(&b'?'), "{what}: refused: {out:?}");
}

/// The job's setup and the indexer as the coordinator drives it: the job's gearing at the
/// translator's pulse limit, the start velocity commanded.
fn indexer_of(job: &Job) -> (paths::Setup, IndexerSetup) {
    let (setup, _) = cell::plan::tool::setup(job);
    let drive = Drive::new(setup.gearing, TRANSLATOR_LIMIT_PPS).unwrap();
    let indexer = IndexerSetup {
        drive,
        start_velocity_command: true,
    };
    (setup, indexer)
}

fn check_indexer(name: &str) {
    let (job, plan) = planned(name);
    let path = &plan.paths[0];
    let ind = cell::plan::tool::mandrel_file(&job, path);
    let (setup, indexer) = indexer_of(&job);
    let drive = indexer.drive;
    let program = transfer::indexer_program(&ind, &indexer).unwrap();
    let clock = mandrel_drive::sim::VirtualClock::new();
    let mut card = Card::new(Machine::new(drive, PULL_IN_SPS), 1);
    send_x(&mut card, &clock, &program.init);
    run_x_move(&mut card, &clock, &program.path_move, name);
    let m = card.machine();
    assert_eq!(m.counter_steps(), ind.path_move.steps);
    assert_eq!(m.motor_steps(), ind.path_move.steps);
    let last = path.plan.segments.last().unwrap().pose.mandrel_rad;
    let commanded = last - path.plan.start.mandrel_rad;
    let half_step = setup.gearing.step_angle_rad() / 2.0;
    let angle = m.mandrel_angle_rad();
    eprintln!(
        "{name} indexer: {} steps of {} in {:.2} s, angle {:.6} rad, commanded {:.6} rad",
        m.counter_steps(),
        ind.path_move.steps,
        clock.now_s(),
        angle,
        commanded
    );
    assert!(
        (angle - commanded).abs() <= half_step,
        "{name}: mandrel at {angle} rad, plan's last commanded angle {commanded} rad"
    );
    // The file's `reset` record returns the indexer to power-up.
    for cmd in &program.reset {
        card.receive(
            format!("{}\r", xlang::encode(Some(1), cmd)).as_bytes(),
            clock.now_s(),
        );
    }
    assert_eq!(card.machine().counter_steps(), 0);
}

/// Discrete movement sends each .ROB instruction's mandrel move with its robot move: the moves
/// add up to the .IND file's steps.
fn check_discrete_mandrel_moves(name: &str) {
    let (job, plan) = planned(name);
    let path = &plan.paths[0];
    let rob = cell::plan::tool::robot_file(&job, path).unwrap();
    let ind = cell::plan::tool::mandrel_file(&job, path);
    let (_, indexer) = indexer_of(&job);
    let drive = indexer.drive;
    let clock = mandrel_drive::sim::VirtualClock::new();
    let mut card = Card::new(Machine::new(drive, PULL_IN_SPS), 1);
    send_x(
        &mut card,
        &clock,
        &transfer::indexer_program(&ind, &indexer).unwrap().init,
    );
    let mut sum = 0;
    for i in &rob.instructions {
        let cmds = transfer::indexer_move(&i.mandrel, &indexer, Some(i.number)).unwrap();
        run_x_move(
            &mut card,
            &clock,
            &cmds,
            &format!("{name} instruction {}", i.number),
        );
        sum += i.mandrel.steps;
        assert_eq!(
            card.machine().counter_steps(),
            sum,
            "{name} instruction {}",
            i.number
        );
    }
    assert_eq!(sum, ind.path_move.steps);
    eprintln!(
        "{name} discrete indexer: {} moves, {sum} steps in {:.2} s",
        rob.instructions.len(),
        clock.now_s()
    );
}

#[test]
fn ind_moves_run_on_the_simulated_indexer() {
    check_discrete_mandrel_moves("sbend");
    check_indexer("sbend");
    check_indexer("cylinder");
}
