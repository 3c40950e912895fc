//! From control files to device commands (seed 001 §5.4, §5.6): a parsed `.ROB` file becomes
//! robot telegrams, a parsed `.IND` file becomes X-language indexer commands. Pure: no I/O.
//!
//! **Robot** (`docs/protocol.md` §4, §5). Each `instr` becomes a positioning instruction:
//!
//! - `pos_mm` → x, y, z at 0.0625 mm per LSB (seed 001 §5.4.1), rounded to the nearest LSB;
//!   outside ±2047.9375 mm (−2048.0 refused, spec §5.6) is an error, never a clamp.
//! - `q` (scalar first, App. A) → the Q1.14 quaternion, normalised, canonical sign (q1 ≥ 0).
//! - `move=rect|joint` → rectangular or joint ("robot") interpolation; `ref=abs|rel` → absolute
//!   or relative (§5.3.2).
//! - `speed_pct` → the telegram's speed, which is a fraction of the base speed at 1/8192 per LSB
//!   (§5.4.1: "given as a percentage of the specified base velocity"; 8192 = 100 %). A fraction
//!   that does not fit (above 7.99988) or rounds to zero is an error naming the instruction.
//! - the header's `movement` → the zone: fine = 1 mm, medium = 10 mm (§5.4.2). Discrete movement
//!   is no zone: its positions go one at a time as immediate moves ([`immediate_moves`]), the
//!   arm stopping at each.
//! - the header's base and maximum speeds → SET_BASE_SPEED and SET_MAX_SPEED in m/s at 1/8192
//!   m/s per LSB.
//!
//! A stored program opens with the start handshake ([`PROLOGUE_LEN`] control instructions: "in
//! position" output [`IN_POSITION_OUTPUT`] lowered, then a wait for the PC's start on input
//! [`START_INPUT`]; seed 001 §5.6.4 steps 10–11, App. D), so the `.ROB` instruction `n` is stored
//! as instruction `n + PROLOGUE_LEN`. It ends with "in position" raised and `End`, so the PC sees
//! on the sync line when the robot has reached the last point.
//!
//! **Indexer** (`docs/mandrel-drive.md`). A mandrel move (`accel_rps2`, `start_rps`, `max_rps`,
//! `steps`, all at the mandrel) is checked by [`mandrel_drive::Profile::validate`] (signs,
//! ordering, translator pulse limit) and converted to motor units by [`mandrel_drive::Drive`]:
//! `A` motor rev/s², `V` motor rev/s, `VS` start/stop velocity (only where the indexer has it), then
//! a preset incremental move of the file's steps (`MN MPI D<steps> G`) and the move-complete
//! notification `CR`.

use asea_protocol::command::{IN_POSITION_OUTPUT, START_INPUT};

pub use crate::plan::program::{
    PROGRAM_CONTROL_INSTRUCTIONS, PROLOGUE_LEN, max_positioning_instructions,
};

use asea_protocol::{
    Command, Control, EncodeError, Flags, Instruction, Interpolation, Pose, Positioning, Reference,
    Speed, Zone,
};
use mandrel_drive::xlang::Command as XCommand;
use mandrel_drive::{Drive, Profile};
use sequences::rob::{self, Header, Movement};
use sequences::{MandrelFile, MandrelMove, RobotFile};

use crate::Error;

/// Millimetres per metre: the telegram's base and maximum speeds are in m/s.
const MM_PER_M: f64 = 1000.0;

/// The zone of a stored program's positions, `None` for discrete movement (seed 001 §5.4.2).
pub fn zone(movement: Movement) -> Option<Zone> {
    match movement {
        Movement::Discrete => None,
        Movement::Fine => Some(Zone::Fine),
        Movement::Medium | Movement::Continuous => Some(Zone::Medium),
    }
}

/// A robot control file as the robot's telegrams.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotProgram {
    /// Program number (the `program` header record).
    pub program: u8,
    /// SET_BASE_SPEED value, m/s.
    pub base_speed: Speed,
    /// SET_MAX_SPEED value, m/s.
    pub max_speed: Speed,
    /// The stored program: one positioning per `instr` (robot instruction `n` is the file's
    /// `instr n`), then "in position" and `End`.
    pub instructions: Vec<Instruction>,
}

impl RobotProgram {
    /// The speed telegrams to send before running the program: base, then maximum.
    pub fn speed_commands(&self) -> [Command; 2] {
        [
            Command::SetBaseSpeed(self.base_speed),
            Command::SetMaxSpeed(self.max_speed),
        ]
    }
}

/// The header's base and maximum speeds as telegram values (m/s, 1/8192 m/s per LSB).
pub fn speeds(header: &Header) -> Result<(Speed, Speed), Error> {
    let at_header = |source| Error::RobotTransfer {
        program: header.program,
        instruction: None,
        source,
    };
    let base = metres_per_second("base_speed", header.base_speed_mm_s).map_err(at_header)?;
    let max = metres_per_second("max_speed", header.max_speed_mm_s).map_err(at_header)?;
    Ok((base, max))
}

fn metres_per_second(name: &'static str, mm_s: f64) -> Result<Speed, EncodeError> {
    let speed = Speed::from_value(name, mm_s / MM_PER_M)?;
    if speed.0 == 0 {
        return Err(EncodeError::OutOfRange {
            name,
            value: mm_s / MM_PER_M,
            expected: "at least 1/8192 m/s",
        });
    }
    Ok(speed)
}

/// One `.ROB` instruction as a positioning telegram in `zone`. Errors name nothing; the callers
/// add the program and instruction.
pub fn positioning(instruction: &rob::Instruction, zone: Zone) -> Result<Positioning, EncodeError> {
    let fraction = instruction.speed_pct / 100.0;
    let speed = Speed::from_value("speed", fraction)?;
    if speed.0 == 0 {
        return Err(EncodeError::OutOfRange {
            name: "speed",
            value: fraction,
            expected: "at least 1/8192 of the base speed",
        });
    }
    Ok(Positioning {
        flags: Flags {
            interpolation: match instruction.interpolation {
                rob::Interpolation::Rectangular => Interpolation::Rectangular,
                rob::Interpolation::Joint => Interpolation::Joint,
            },
            reference: match instruction.reference {
                rob::Reference::Absolute => Reference::Absolute,
                rob::Reference::Relative => Reference::Relative,
            },
            zone,
        },
        pose: Pose::from_mm(instruction.position_mm, instruction.q)?,
        speed,
    })
}

/// The stored program of a fine or medium `.ROB` file (seed 001 §5.4.2, §5.6.1). A discrete file
/// is refused ([`Error::DiscreteProgram`]): use [`immediate_moves`].
pub fn robot_program(file: &RobotFile) -> Result<RobotProgram, Error> {
    let program = file.header.program;
    let zone = zone(file.header.movement).ok_or(Error::DiscreteProgram { program })?;
    let (base_speed, max_speed) = speeds(&file.header)?;
    let mut instructions = Vec::with_capacity(file.instructions.len() + 4);
    instructions.push(Instruction::Control(Control::SetOutput {
        line: IN_POSITION_OUTPUT,
        on: false,
    }));
    instructions.push(Instruction::Control(Control::WaitInput {
        line: START_INPUT,
        on: true,
    }));
    for i in &file.instructions {
        let p = positioning(i, zone).map_err(|source| Error::RobotTransfer {
            program,
            instruction: Some(i.number),
            source,
        })?;
        instructions.push(Instruction::Position(p));
    }
    instructions.push(Instruction::Control(Control::SetOutput {
        line: IN_POSITION_OUTPUT,
        on: true,
    }));
    instructions.push(Instruction::Control(Control::End));
    Ok(RobotProgram {
        program,
        base_speed,
        max_speed,
        instructions,
    })
}

/// Discrete movement (seed 001 §5.4.1): every `.ROB` instruction as an immediate move, sent one
/// at a time; the arm stops at each point and raises output [`IN_POSITION_OUTPUT`]. Any file can
/// be run this way ("alone, a .ROB file drives discrete mode"); the zone bits are fine, as
/// MOVE_IMMEDIATE requires.
pub fn immediate_moves(file: &RobotFile) -> Result<Vec<Command>, Error> {
    file.instructions
        .iter()
        .map(|i| {
            positioning(i, Zone::Fine)
                .map(Command::MoveImmediate)
                .map_err(|source| Error::RobotTransfer {
                    program: file.header.program,
                    instruction: Some(i.number),
                    source,
                })
        })
        .collect()
}

/// What the indexer needs to know that the control files do not say. The default is the thesis
/// drive without a start-velocity command.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct IndexerSetup {
    /// Motor, belt and translator: every unit conversion.
    pub drive: Drive,
    /// The indexer has a start/stop velocity command (`VS`, our simulator). Without it a move
    /// with a start velocity is refused, never sent without it.
    pub start_velocity_command: bool,
}

/// One mandrel move as X-language commands: `A`, `V`, (`VS`), `MN`, `MPI`, `D<steps>`, `G`, `CR`
/// (seed 001 §5.3.2). `instruction` names the `.ROB` instruction in errors (`None` for a `.IND`
/// move).
pub fn indexer_move(
    mv: &MandrelMove,
    setup: &IndexerSetup,
    instruction: Option<u16>,
) -> Result<Vec<XCommand>, Error> {
    let fail = |source| Error::IndexerTransfer {
        instruction,
        source,
    };
    let drive = setup.drive;
    let profile = Profile {
        accel_rps2: mv.accel_rps2,
        start_rps: mv.start_stop_rps,
        max_rps: mv.max_rps,
    };
    let (accel, velocity) =
        mandrel_drive::xlang::accel_and_velocity(&profile, &drive).map_err(fail)?;
    let mut out = vec![XCommand::Accel(accel), XCommand::Velocity(velocity)];
    if setup.start_velocity_command {
        out.push(XCommand::StartVelocity(drive.motor_rps(profile.start_rps)));
    } else if profile.start_rps > 0.0 {
        return Err(fail(mandrel_drive::Error::Unsupported {
            dialect: "the X-language",
            feature: "start/stop velocity command",
        }));
    }
    out.extend([
        XCommand::Preset,
        XCommand::Incremental,
        XCommand::Distance(mv.steps),
        XCommand::Go,
        XCommand::Notify,
    ]);
    Ok(out)
}

/// A `.IND` file as X-language commands, record by record (seed 001 §5.6.2).
#[derive(Debug, Clone, PartialEq)]
pub struct IndexerProgram {
    /// `init`: the motor resolution (`MR`, steps per motor revolution) and a zeroed position
    /// counter (`PZ`), so that the counter afterwards is the path's step count.
    pub init: Vec<XCommand>,
    /// `move`: the whole path in one move ([`indexer_move`]).
    pub path_move: Vec<XCommand>,
    /// `reset`: back to power-up (`Z`; zeroes the counters, busy for 1 s).
    pub reset: Vec<XCommand>,
    /// The move's signed motor steps.
    pub steps: i64,
}

/// The indexer commands of a `.IND` file.
pub fn indexer_program(file: &MandrelFile, setup: &IndexerSetup) -> Result<IndexerProgram, Error> {
    Ok(IndexerProgram {
        init: vec![
            XCommand::Resolution(setup.drive.gearing.steps_per_motor_rev),
            XCommand::Zero,
        ],
        path_move: indexer_move(&file.path_move, setup, None)?,
        reset: vec![XCommand::Reset],
        steps: file.path_move.steps,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use asea_protocol::command::{LENGTH_MM_PER_LSB, QUATERNION_PER_LSB, SPEED_PER_LSB};
    use asea_protocol::{FrameConfig, Quaternion};

    const ROB: &str = "\
rob 1
program 3
base_speed_mm_s 1000
max_speed_mm_s 2000
movement medium
sync_mandrel_deg 91.2
instr 1 speed_pct=10 pos_mm=724.1,20.15,227.93 q=0.9102,-0.0352,0.4124,0.0159 move=rect ref=abs accel_rps2=1 start_rps=0.05 max_rps=0.1 steps=0
instr 2 speed_pct=1.03 pos_mm=730.0625,-25.3,240.5 q=-0.5,0.5,0.5,-0.5 move=joint ref=rel accel_rps2=1 start_rps=0.05 max_rps=0.1 steps=-75
instr 3 speed_pct=200 pos_mm=-2047.9375,2047.9375,0 q=1,0,0,0 move=rect ref=abs accel_rps2=1 start_rps=0.05 max_rps=0.1 steps=12
end
";

    fn file() -> RobotFile {
        RobotFile::parse(ROB).unwrap()
    }

    /// Golden conversion of one instruction: the fields and the STORE_POS telegram's bytes.
    #[test]
    fn golden_instruction() {
        let f = file();
        let p = positioning(&f.instructions[1], Zone::Medium).unwrap();
        assert_eq!(
            p.flags,
            Flags {
                interpolation: Interpolation::Joint,
                reference: Reference::Relative,
                zone: Zone::Medium,
            }
        );
        // 730.0625 / 0.0625 = 11681; −25.3 / 0.0625 = −404.8 → −405; 240.5 → 3848.
        assert_eq!((p.pose.x.0, p.pose.y.0, p.pose.z.0), (11681, -405, 3848));
        // (−0.5, 0.5, 0.5, −0.5) has unit norm; the canonical sign makes q1 ≥ 0.
        assert_eq!(p.pose.q, Quaternion([8192, -8192, -8192, 8192]));
        // 1.03 % of the base speed: 0.0103 × 8192 = 84.38 → 84. Check value: Sum8 of CMD through
        // ETX = 0xC6.
        assert_eq!(p.speed, Speed(84));
        let bytes = Command::StorePos {
            program: 3,
            instruction: 2,
            positioning: p,
        }
        .encode(&FrameConfig::default())
        .unwrap();
        assert_eq!(
            bytes,
            [
                0x02, 0x01, 0x14, 0x03, 0x00, 0x02, 0x07, 0x2D, 0xA1, 0xFE, 0x6B, 0x0F, 0x08, 0x20,
                0x00, 0xE0, 0x00, 0xE0, 0x00, 0x20, 0x00, 0x00, 0x54, 0x03, 0xC6
            ]
        );
    }

    /// .ROB → telegrams → back to pos / q / speed within the telegram resolution.
    #[test]
    fn round_trip_within_resolution() {
        let f = file();
        let prog = robot_program(&f).unwrap();
        assert_eq!(prog.program, 3);
        assert_eq!(prog.instructions.len(), f.instructions.len() + 4);
        assert_eq!(
            prog.instructions[..2],
            [
                Instruction::Control(Control::SetOutput {
                    line: IN_POSITION_OUTPUT,
                    on: false
                }),
                Instruction::Control(Control::WaitInput {
                    line: START_INPUT,
                    on: true
                })
            ]
        );
        assert_eq!(prog.base_speed, Speed(8192));
        assert_eq!(prog.max_speed, Speed(16384));
        assert_eq!(
            prog.instructions[5..],
            [
                Instruction::Control(Control::SetOutput {
                    line: IN_POSITION_OUTPUT,
                    on: true
                }),
                Instruction::Control(Control::End)
            ]
        );
        for (i, t) in f.instructions.iter().zip(&prog.instructions[2..]) {
            let Instruction::Position(p) = t else {
                panic!("instruction {} is not a positioning", i.number);
            };
            assert_eq!(p.flags.zone, Zone::Medium);
            for (got, want) in p.pose.xyz_mm().iter().zip(i.position_mm) {
                assert!(
                    (got - want).abs() <= LENGTH_MM_PER_LSB / 2.0,
                    "{got} vs {want}"
                );
            }
            let n = i.q.iter().map(|c| c * c).sum::<f64>().sqrt();
            let sign = if i.q[0] < 0.0 { -1.0 } else { 1.0 };
            for (got, want) in p.pose.q.wxyz().iter().zip(i.q) {
                let want = sign * want / n;
                assert!(
                    (got - want).abs() <= QUATERNION_PER_LSB / 2.0,
                    "{got} vs {want}"
                );
            }
            let pct = p.speed.value() * 100.0;
            assert!((pct - i.speed_pct).abs() <= 100.0 * SPEED_PER_LSB / 2.0);
        }
        // Re-parsed from the wire, the program is the same.
        for (n, t) in (1u16..).zip(&prog.instructions) {
            let cmd = asea_protocol::client::store_command(3, n, t);
            let bytes = cmd.encode(&FrameConfig::default()).unwrap();
            let frame = asea_protocol::Frame {
                code: bytes[1],
                data: bytes[3..3 + usize::from(bytes[2])].to_vec(),
            };
            assert_eq!(Command::from_frame(&frame).unwrap(), cmd);
        }
    }

    #[test]
    fn speed_out_of_range_names_the_instruction() {
        // 900 % of a 100 mm/s base is a fraction of 9, beyond the telegram's 7.99988.
        let text = ROB
            .replace("base_speed_mm_s 1000", "base_speed_mm_s 100")
            .replace("speed_pct=200", "speed_pct=900");
        let f = RobotFile::parse(&text).unwrap();
        let e = robot_program(&f).unwrap_err();
        assert!(e.is_input());
        assert!(matches!(
            e,
            Error::RobotTransfer {
                program: 3,
                instruction: Some(3),
                source: EncodeError::OutOfRange { name: "speed", .. }
            }
        ));
        assert_eq!(
            e.to_string(),
            "program 3: instruction 3: speed = 9 out of range (0 to 7.99988 (1/8192 per LSB))"
        );
        // A speed that rounds to zero would stop the robot's program: refused too.
        let slow = ROB.replace("speed_pct=10 ", "speed_pct=0.001 ");
        let e = immediate_moves(&RobotFile::parse(&slow).unwrap()).unwrap_err();
        assert!(e.to_string().starts_with("program 3: instruction 1: speed"));
        // Header speeds beyond 7.99988 m/s.
        let fast = ROB.replace("max_speed_mm_s 2000", "max_speed_mm_s 9000");
        let e = robot_program(&RobotFile::parse(&fast).unwrap()).unwrap_err();
        assert!(e.to_string().starts_with("program 3: header: max_speed"));
    }

    #[test]
    fn position_out_of_range_names_the_instruction() {
        let text = ROB.replace("pos_mm=-2047.9375,", "pos_mm=-2048,");
        let f = RobotFile::parse(&text).unwrap();
        let e = robot_program(&f).unwrap_err();
        assert!(e.is_input());
        assert_eq!(
            e.to_string(),
            "program 3: instruction 3: x = -2048 out of range (-2047.9375 to 2047.9375 mm)"
        );
        let text = ROB.replace("227.93 q", "2048 q");
        let e = immediate_moves(&RobotFile::parse(&text).unwrap()).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("program 3: instruction 1: z = 2048")
        );
    }

    /// Non-finite and extreme values are typed errors, never panics.
    #[test]
    fn extreme_values_are_errors() {
        let base = file().instructions[0];
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e300, -1e300] {
            for k in 0..3 {
                let mut i = base;
                i.position_mm[k] = bad;
                assert!(positioning(&i, Zone::Fine).is_err());
            }
            let mut i = base;
            i.speed_pct = bad;
            assert!(positioning(&i, Zone::Fine).is_err());
            let mut i = base;
            i.q = [bad, 0.0, 0.0, 0.0];
            // ±1e300 squared overflows the norm: refused like the non-finite values.
            assert!(matches!(
                positioning(&i, Zone::Fine),
                Err(EncodeError::DegenerateQuaternion(..))
            ));
            let mut mv = base.mandrel;
            mv.accel_rps2 = bad;
            assert!(indexer_move(&mv, &IndexerSetup::default(), Some(1)).is_err());
            let mut mv = base.mandrel;
            mv.start_stop_rps = 0.0;
            mv.max_rps = bad;
            assert!(indexer_move(&mv, &IndexerSetup::default(), Some(1)).is_err());
        }
        let mut i = base;
        i.q = [0.0; 4];
        assert!(matches!(
            positioning(&i, Zone::Fine),
            Err(EncodeError::DegenerateQuaternion(..))
        ));
    }

    #[test]
    fn zones_and_discrete_movement() {
        assert_eq!(zone(Movement::Fine).map(Zone::radius_mm), Some(1.0));
        assert_eq!(zone(Movement::Medium).map(Zone::radius_mm), Some(10.0));
        assert_eq!(zone(Movement::Discrete), None);
        let text = ROB.replace("movement medium", "movement discrete");
        let f = RobotFile::parse(&text).unwrap();
        assert!(matches!(
            robot_program(&f),
            Err(Error::DiscreteProgram { program: 3 })
        ));
        let moves = immediate_moves(&f).unwrap();
        assert_eq!(moves.len(), 3);
        for m in moves {
            let Command::MoveImmediate(p) = m else {
                panic!("not an immediate move: {m:?}");
            };
            assert_eq!(p.flags.zone, Zone::Fine);
        }
    }

    #[test]
    fn indexer_commands_through_the_drive_units() {
        let ind = MandrelFile::parse(
            "ind 1\ninit\nmove accel_rps2=1 start_rps=0.05 max_rps=0.1 steps=-3225\nreset\n",
        )
        .unwrap();
        let setup = IndexerSetup {
            start_velocity_command: true,
            ..IndexerSetup::default()
        };
        let p = indexer_program(&ind, &setup).unwrap();
        let text: Vec<String> = p
            .init
            .iter()
            .chain(&p.path_move)
            .chain(&p.reset)
            .map(|c| mandrel_drive::xlang::encode(Some(1), c))
            .collect();
        // 60/13 motor revolutions per mandrel revolution: 1 → 4.62, 0.1 → 0.46, 0.05 → 0.23.
        assert_eq!(
            text,
            [
                "1MR400", "1PZ", "1A4.62", "1V0.46", "1VS0.23", "1MN", "1MPI", "1D-3225", "1G",
                "1CR", "1Z"
            ]
        );
        assert_eq!(p.steps, -3225);
        // Without a start-velocity command, a start velocity is refused, not dropped.
        let e = indexer_program(&ind, &IndexerSetup::default()).unwrap_err();
        assert!(e.is_input());
        assert_eq!(
            e.to_string(),
            "mandrel move: the X-language has no start/stop velocity command"
        );
        // Over the translator's pulse limit: 6 rev/s × 1846.15 = 11077 pulses/s.
        let f = file();
        let mut mv = f.instructions[1].mandrel;
        mv.max_rps = 6.0;
        let e = indexer_move(&mv, &setup, Some(2)).unwrap_err();
        assert_eq!(
            e.to_string(),
            "instruction 2: mandrel move: 11077 pulses/s exceeds the translator limit of 10000 pulses/s"
        );
        // Below the X-language's smallest acceleration.
        mv.max_rps = 0.1;
        mv.accel_rps2 = 0.001;
        let e = indexer_move(&mv, &setup, Some(2)).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("instruction 2: mandrel move: accel")
        );
    }
}
