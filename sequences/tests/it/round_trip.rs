//! Every operator file windcell writes reads back as the value written (parse → write → parse
//! gives an equal value and the same text), over random files; and the writers refuse what the
//! readers refuse, with [`Error::Unwritable`].

use proptest::prelude::*;
use sequences::job::{Direction, Job, MAX_SEGMENTS, MIN_SEGMENTS};
use sequences::rob::{Header, Instruction, Interpolation, Reference};
use sequences::{Error, MandrelFile, MandrelMove, Movement, RobotFile, RunFile, SequenceFile};
use toml::Spanned;

fn mandrel_move() -> impl Strategy<Value = MandrelMove> {
    (
        1e-3..50.0f64,
        1e-3..10.0f64,
        0.0..=1.0f64,
        -5_000_000i64..5_000_000,
    )
        .prop_map(|(accel_rps2, max_rps, start_fraction, steps)| MandrelMove {
            accel_rps2,
            start_stop_rps: max_rps * start_fraction,
            max_rps,
            steps,
        })
}

fn unit_quaternion() -> impl Strategy<Value = [f64; 4]> {
    [-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64]
        .prop_filter("not near zero", |q| {
            q.iter().map(|c| c * c).sum::<f64>() > 1e-3
        })
        .prop_map(|q| {
            let n = q.iter().map(|c| c * c).sum::<f64>().sqrt();
            q.map(|c| c / n)
        })
}

fn robot_file() -> impl Strategy<Value = RobotFile> {
    let header = (
        1u8..=255,
        1.0..5000.0f64,
        1.0..4.0f64,
        prop::sample::select(vec![
            Movement::Discrete,
            Movement::Fine,
            Movement::Medium,
            Movement::Continuous,
        ]),
        -1e4..1e4f64,
    );
    let instruction = (
        1e-4..=1.0f64,
        [-2000.0..2000.0f64, -2000.0..2000.0f64, -500.0..2500.0f64],
        unit_quaternion(),
        any::<bool>(),
        any::<bool>(),
        mandrel_move(),
    );
    (header, prop::collection::vec(instruction, 1..12)).prop_map(
        |((program, base, ratio, movement, sync), instructions)| RobotFile {
            header: Header {
                program,
                base_speed_mm_s: base,
                max_speed_mm_s: base * ratio,
                movement,
                sync_mandrel_deg: sync,
            },
            instructions: instructions
                .into_iter()
                .enumerate()
                .map(
                    |(k, (fraction, position_mm, q, rect, abs, mandrel))| Instruction {
                        number: k as u16 + 1,
                        // Up to the maximum speed, never 0.
                        speed_pct: 100.0 * ratio * fraction,
                        position_mm,
                        q,
                        interpolation: if rect {
                            Interpolation::Rectangular
                        } else {
                            Interpolation::Joint
                        },
                        reference: if abs {
                            Reference::Absolute
                        } else {
                            Reference::Relative
                        },
                        mandrel,
                    },
                )
                .collect(),
        },
    )
}

/// The cylinder job of the examples with its first path only, as text.
const CYLINDER: &str = include_str!("../data/cylinder-one-path.toml");

/// A value for a job field; the span is irrelevant to equality.
fn at<T>(value: T) -> Spanned<T> {
    Spanned::new(0..0, value)
}

#[derive(Debug, Clone)]
struct PathChoice {
    program: u8,
    down: bool,
    wind_angle_deg: f64,
    start_angle_deg: f64,
    segments: u32,
    dxf: Option<(String, Option<f64>)>,
}

fn path_choice() -> impl Strategy<Value = PathChoice> {
    (
        1u8..=255,
        any::<bool>(),
        0.01..89.99f64,
        -720.0..720.0f64,
        MIN_SEGMENTS..=MAX_SEGMENTS,
        prop::option::of(("[a-z]{1,8}\\.dxf", prop::option::of(0.01..10.0f64))),
    )
        .prop_map(
            |(program, down, wind_angle_deg, start_angle_deg, segments, dxf)| PathChoice {
                program,
                down,
                wind_angle_deg,
                start_angle_deg,
                segments,
                dxf,
            },
        )
}

fn job() -> impl Strategy<Value = Job> {
    (
        "[A-Za-z0-9_-]{1,12}",
        (
            100.0..3000.0f64,
            -500.0..1500.0f64,
            0.01..2.0f64,
            0.0..400.0f64,
        ),
        (1.0..300.0f64, 1.0..2000.0f64, 1.0..3.0f64),
        prop::sample::select(vec![
            Movement::Discrete,
            Movement::Fine,
            Movement::Medium,
            Movement::Continuous,
        ]),
        (
            1u32..100_000,
            1u32..200,
            1u32..200,
            0.01..20.0f64,
            0.0..1.0f64,
        ),
        (
            1.0..400.0f64,
            prop::option::of((-100.0..100.0f64, -100.0..100.0f64)),
        ),
        prop::collection::vec(path_choice(), 1..5),
    )
        .prop_map(|(name, cell, speeds, movement, drive, mandrel, paths)| {
            let mut job = Job::parse(CYLINDER).unwrap();
            job.name = at(name);
            let c = &mut job.cell;
            let (b, height, mandrel_rps, eye) = cell;
            c.robot_distance_mm = at(b);
            c.start_height_mm = at(height);
            c.mandrel_speed_rps = at(mandrel_rps);
            c.eye_mechanism_length_mm = at(eye);
            let (offset, base, ratio) = speeds;
            c.offset_mm = at(offset);
            c.base_speed_mm_s = at(base);
            c.max_speed_mm_s = at(base * ratio);
            c.movement = at(movement);
            let (steps, motor, wheel, accel, start_fraction) = drive;
            c.drive.steps_per_rev = at(steps);
            c.drive.gear_ratio = at([motor, wheel]);
            c.drive.accel_rps2 = at(accel);
            c.drive.start_stop_rps = at(mandrel_rps * start_fraction);
            let (diameter, offsets) = mandrel;
            job.mandrel.diameter_mm = at(diameter);
            // Long enough for any tilt.
            job.mandrel.length_mm = Some(at(500.0));
            job.mandrel.bottom_offset_mm = offsets.map(|o| at(o.0));
            job.mandrel.top_offset_mm = offsets.map(|o| at(o.1));
            let template = job.paths[0].clone();
            let mut used = Vec::new();
            job.paths = paths
                .into_iter()
                .filter(|p| {
                    let fresh = !used.contains(&p.program);
                    used.push(p.program);
                    fresh
                })
                .map(|p| {
                    let mut spec = template.clone();
                    spec.program = at(p.program);
                    spec.segments = at(p.segments);
                    match p.dxf {
                        Some((file, tolerance)) => {
                            spec.direction = None;
                            spec.wind_angle_deg = None;
                            spec.start_angle_deg = None;
                            spec.dxf = Some(at(file));
                            spec.surface_tolerance_mm = tolerance.map(at);
                        }
                        None => {
                            spec.direction = Some(at(if p.down {
                                Direction::Down
                            } else {
                                Direction::Up
                            }));
                            spec.wind_angle_deg = Some(at(p.wind_angle_deg));
                            spec.start_angle_deg = Some(at(p.start_angle_deg));
                        }
                    }
                    spec
                })
                .collect();
            job
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn robot_files_round_trip(file in robot_file()) {
        let text = file.write().unwrap();
        let back = RobotFile::parse(&text).unwrap();
        prop_assert_eq!(&back, &file);
        prop_assert_eq!(back.write().unwrap(), text);
    }

    #[test]
    fn mandrel_files_round_trip(path_move in mandrel_move()) {
        let file = MandrelFile { path_move };
        let text = file.write().unwrap();
        let back = MandrelFile::parse(&text).unwrap();
        prop_assert_eq!(back, file);
        prop_assert_eq!(back.write().unwrap(), text);
    }

    #[test]
    fn sequence_files_round_trip(names in prop::collection::vec("[A-Za-z0-9_-]{1,16}", 1..20)) {
        let file = SequenceFile { names };
        let text = file.write().unwrap();
        let back = SequenceFile::parse(&text).unwrap();
        prop_assert_eq!(&back, &file);
        prop_assert_eq!(back.write().unwrap(), text);
    }

    #[test]
    fn run_files_round_trip(programs in prop::collection::vec(1u8..=255, 1..20)) {
        let file = RunFile { programs };
        let text = file.write().unwrap();
        let back = RunFile::parse(&text).unwrap();
        prop_assert_eq!(&back, &file);
        prop_assert_eq!(back.write().unwrap(), text);
    }

    #[test]
    fn job_files_round_trip(job in job()) {
        let text = job.write().unwrap();
        let back = Job::parse(&text).unwrap();
        prop_assert_eq!(&back, &job);
        prop_assert_eq!(back.write().unwrap(), text);
    }

    /// A robot file damaged in one field is refused by the writer exactly when the reader refuses
    /// its text.
    #[test]
    fn robot_writer_refuses_what_the_reader_refuses(
        file in robot_file(),
        which in 0usize..8,
        bad in prop::sample::select(vec![0.0, -1.0, f64::NAN, f64::INFINITY, 1e9]),
    ) {
        let mut damaged = file.clone();
        let last = damaged.instructions.len() - 1;
        match which {
            0 => damaged.header.base_speed_mm_s = bad,
            1 => damaged.header.max_speed_mm_s = bad,
            2 => damaged.header.sync_mandrel_deg = bad,
            3 => damaged.instructions[last].speed_pct = bad,
            4 => damaged.instructions[last].position_mm[1] = bad,
            5 => damaged.instructions[last].q[0] = bad,
            6 => damaged.instructions[last].mandrel.accel_rps2 = bad,
            _ => damaged.instructions[last].mandrel.max_rps = bad,
        }
        let unchanged = damaged == file;
        match damaged.write() {
            Ok(text) => {
                prop_assert_eq!(&RobotFile::parse(&text).unwrap(), &damaged);
            }
            Err(e) => {
                prop_assert!(!unchanged, "{}", e);
                prop_assert!(matches!(e, Error::Unwritable { .. }), "{}", e);
            }
        }
        // Non-finite numbers, zero and negative speeds never pass.
        if !bad.is_finite() || (bad <= 0.0 && matches!(which, 0 | 1 | 3 | 6 | 7)) {
            prop_assert!(damaged.write().is_err());
        }
    }
}

#[test]
fn writers_refuse_empty_files_and_program_zero() {
    let unwritable = |r: Result<String, Error>| match r {
        Err(Error::Unwritable {
            format,
            line,
            message,
            ..
        }) => format!("{format} {line} {message}"),
        other => panic!("expected Unwritable, got {other:?}"),
    };
    assert!(unwritable(SequenceFile { names: vec![] }.write()).contains("names no control file"));
    assert!(
        unwritable(
            SequenceFile {
                names: vec!["A_1".into(), "B 2".into()]
            }
            .write()
        )
        .starts_with("sequence file 2 ")
    );
    // `#` starts a comment: `A#B` would read back as `A`.
    assert!(
        unwritable(
            SequenceFile {
                names: vec!["A#B".into()]
            }
            .write()
        )
        .contains("different value")
    );
    assert!(unwritable(RunFile { programs: vec![] }.write()).contains("names no program"));
    assert!(
        unwritable(
            RunFile {
                programs: vec![1, 0]
            }
            .write()
        )
        .starts_with("run file 2 ")
    );
    let mandrel = MandrelMove {
        accel_rps2: 1.0,
        start_stop_rps: 0.05,
        max_rps: 0.1,
        steps: 10,
    };
    let robot = RobotFile {
        header: Header {
            program: 1,
            base_speed_mm_s: 1000.0,
            max_speed_mm_s: 2000.0,
            movement: Movement::Fine,
            sync_mandrel_deg: 0.0,
        },
        instructions: vec![],
    };
    assert!(unwritable(robot.write()).contains("no instructions"));
    let mut zero = robot.clone();
    zero.header.program = 0;
    assert!(unwritable(zero.write()).contains("out of range 1..=255"));
    let instruction = Instruction {
        number: 1,
        speed_pct: 10.0,
        position_mm: [800.0, 0.0, 400.0],
        q: [1.0, 0.0, 0.0, 0.0],
        interpolation: Interpolation::Rectangular,
        reference: Reference::Absolute,
        mandrel,
    };
    let mut skipped = robot.clone();
    skipped.instructions = vec![
        instruction,
        Instruction {
            number: 3,
            ..instruction
        },
    ];
    assert!(unwritable(skipped.write()).contains("out of order"));
    let mut fast = robot;
    fast.instructions = vec![Instruction {
        speed_pct: 250.0,
        ..instruction
    }];
    assert!(unwritable(fast.write()).contains("exceeds the maximum speed"));
    let slow_start = MandrelFile {
        path_move: MandrelMove {
            start_stop_rps: 0.2,
            ..mandrel
        },
    };
    assert!(unwritable(slow_start.write()).contains("start_rps exceeds max_rps"));
    let mut job = Job::parse(CYLINDER).unwrap();
    job.paths[0].program = at(0);
    assert!(unwritable(job.write()).contains("program numbers run from 1"));
    let mut job = Job::parse(CYLINDER).unwrap();
    job.paths.clear();
    assert!(unwritable(job.write()).contains("no [[path]]"));
    let mut job = Job::parse(CYLINDER).unwrap();
    job.paths[0].segments = at(MIN_SEGMENTS - 1);
    assert!(unwritable(job.write()).contains("out of range"));
}

#[test]
fn segment_limits_are_inclusive() {
    for (segments, ok) in [
        (MIN_SEGMENTS - 1, false),
        (MIN_SEGMENTS, true),
        (MAX_SEGMENTS, true),
        (MAX_SEGMENTS + 1, false),
    ] {
        let text = CYLINDER.replace("segments = 50", &format!("segments = {segments}"));
        assert_eq!(Job::parse(&text).is_ok(), ok, "{segments}");
    }
    // 16-bit instruction numbers hold the approach and every segment.
    assert!(MAX_SEGMENTS < u32::from(u16::MAX));
}
