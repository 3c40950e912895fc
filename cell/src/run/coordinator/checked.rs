//! The pre-run check (seed 001 §5.6.4, §4.1.2): every control file converted to the devices'
//! units and ranges, held to the arm's reach and the robot's memory, before anything is sent;
//! what it makes is the [`Batch`] the coordinator winds.

use std::path::PathBuf;

use paths::robot::Arm;
use sequences::syntax::Places;

use super::*;
use crate::error::ControlFileKind;

/// One path of the batch: a robot control file and, for program mode, its mandrel file.
#[derive(Debug, Clone)]
pub struct Item {
    /// Control-file name (`SBEND_1`).
    pub name: String,
    /// The robot control file.
    pub rob: RobotFile,
    /// The mandrel control file (program mode).
    pub ind: Option<MandrelFile>,
    /// Where the files were read and where each value stands in them, so that a refusal names
    /// the file, line and column; `None` for files made in memory (a plan not yet written).
    pub places: Option<ItemPlaces>,
}

/// The paths an item's control files were read from and the places of their values.
#[derive(Debug, Clone)]
pub struct ItemPlaces {
    /// `NAME.ROB` and its values' places.
    pub rob: (PathBuf, Places),
    /// `NAME.IND` and its move's places, when there is one.
    pub ind: Option<(PathBuf, Places)>,
}

impl Item {
    /// A pre-run refusal of this item, naming its control file: its path, line and column when
    /// the item was read from files and one value is at fault ([`Error::control_value`]), else
    /// the file's name ([`Error::in_item`]).
    pub fn refusal(&self, error: Error) -> Error {
        let (Some(places), Some(value)) = (&self.places, error.control_value()) else {
            return error.in_item(&self.name);
        };
        let Some((path, values)) = (match value.kind {
            ControlFileKind::Rob => Some(&places.rob),
            ControlFileKind::Ind => places.ind.as_ref(),
        }) else {
            return error.in_item(&self.name);
        };
        let place = match value.instruction {
            Some(n) => values.instruction(n, value.field, value.part),
            None => values.field(value.field),
        };
        let source = match error {
            Error::ControlFile { source, .. } => source,
            other => Box::new(other),
        };
        Error::ControlFile {
            file: path.display().to_string(),
            place,
            source,
        }
    }
}

/// What the pre-run check made of one item.
#[derive(Debug, Clone)]
pub(super) struct Prepared {
    /// Absolute robot target of each instruction, mm.
    pub(super) targets_mm: Vec<[f64; 3]>,
    /// Each instruction as an immediate move.
    pub(super) immediate: Vec<Positioning>,
    /// The mandrel move of each instruction.
    pub(super) mandrel: Vec<MandrelMove>,
    /// Steps from the path's start after each instruction (index 0 = before the first).
    pub(super) cumulative_steps: Vec<i64>,
    /// The stored program with the handshake (program mode).
    pub(super) program: Option<Vec<Instruction>>,
}

/// The robot's working range the pre-run check holds every instruction to: an envelope, and the
/// arm model whose poses the controller takes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reach {
    /// Greatest horizontal distance from the pedestal axis, mm.
    pub max_radius_mm: f64,
    /// Least horizontal distance, mm.
    pub min_radius_mm: f64,
    /// Lowest and highest height, mm.
    pub z_range_mm: (f64, f64),
    /// The five-axis arm each pose must have a joint solution on ([`Arm::takes_pose`], the
    /// decision the robot controller makes, code 9); `None` holds to the envelope alone.
    pub arm: Option<Arm>,
}

impl Reach {
    /// True when the eye target `t` (cell frame, mm) lies in the range.
    pub fn holds(&self, t: [f64; 3]) -> bool {
        let radius = t[0].hypot(t[1]);
        radius <= self.max_radius_mm
            && radius >= self.min_radius_mm
            && t[2] >= self.z_range_mm.0
            && t[2] <= self.z_range_mm.1
    }

    /// True when the arm can take the pose: eye `t` (mm) with wrist quaternion `q_wxyz`, as the
    /// positioning telegram carries them; always for a range without an arm.
    pub fn arm_takes(&self, t: [f64; 3], q_wxyz: [f64; 4]) -> bool {
        self.arm.is_none_or(|arm| arm.takes_pose(t, q_wxyz))
    }
}

impl Default for Reach {
    /// The robot computer's own range check (`asea_protocol::sim::MotionParams`: 1600 mm,
    /// ±2047.9375 mm of height) and the IRB 6/2's arm.
    fn default() -> Self {
        Reach {
            max_radius_mm: 1600.0,
            min_radius_mm: 0.0,
            z_range_mm: (-2047.9375, 2047.9375),
            arm: Some(Arm::default()),
        }
    }
}

/// A checked batch, ready to wind.
#[derive(Debug, Clone)]
pub struct Batch {
    /// Items in winding order.
    pub items: Vec<Item>,
    /// The mode.
    pub mode: RunMode,
    /// Identifies the job's files (a hash of their texts): a journal names it.
    pub job_id: String,
    /// Motor, belt and translator.
    pub drive: Drive,
    pub(super) prepared: Vec<Prepared>,
}

impl Batch {
    /// The planned time of each instruction of item `k` (index 0 the approach, 0 s: its sync
    /// move depends on where the mandrel stands), s: the mandrel's move as the indexer runs it
    /// (`paths::timing`), which sets the robot's speed for the segment (seed 001 §5.6.2). In
    /// discrete mode each segment is its own move; in program mode the path is one move, shared
    /// among its segments by their steps. Not included: the exchanges that confirm each
    /// discrete segment, homing, the upload.
    pub fn planned_times_s(&self, k: usize) -> Vec<f64> {
        let (Some(item), Some(prep)) = (self.items.get(k), self.prepared.get(k)) else {
            return Vec::new();
        };
        let per_rev = self.drive.steps_per_mandrel_rev();
        let profile = |m: &MandrelMove| MandrelProfile {
            accel_rps2: m.accel_rps2,
            start_stop_rps: m.start_stop_rps,
            max_rps: m.max_rps,
        };
        let mut times: Vec<f64> = match self.mode {
            RunMode::Discrete => prep
                .mandrel
                .iter()
                .map(|m| profile(m).duration_s(m.steps.unsigned_abs(), per_rev))
                .collect(),
            _ => {
                let path_move = item
                    .ind
                    .as_ref()
                    .map_or(prep.mandrel.first().copied(), |f| Some(f.path_move));
                let steps: Vec<u64> = prep
                    .mandrel
                    .iter()
                    .map(|m| m.steps.unsigned_abs())
                    .collect();
                let total: u64 = steps.iter().sum();
                let path_s = path_move.map_or(0.0, |m| profile(&m).duration_s(total, per_rev));
                steps
                    .iter()
                    .map(|&s| {
                        if total == 0 {
                            0.0
                        } else {
                            path_s * s as f64 / total as f64
                        }
                    })
                    .collect()
            }
        };
        if let Some(first) = times.first_mut() {
            *first = 0.0;
        }
        times
    }
}

/// The App. D handshake around a stored program's positions: lower "in position", wait for the
/// PC's start, the positions, raise "in position", End. Control instructions already in
/// `instructions` are replaced, so a program that has its own handshake is not wrapped twice.
pub fn handshake_program(instructions: &[Instruction]) -> Vec<Instruction> {
    let mut out = vec![
        Instruction::Control(Control::SetOutput {
            line: IN_POSITION_OUTPUT,
            on: false,
        }),
        Instruction::Control(Control::WaitInput {
            line: START_INPUT,
            on: true,
        }),
    ];
    out.extend(
        instructions
            .iter()
            .filter(|i| matches!(i, Instruction::Position(_)))
            .copied(),
    );
    out.push(Instruction::Control(Control::SetOutput {
        line: IN_POSITION_OUTPUT,
        on: true,
    }));
    out.push(Instruction::Control(Control::End));
    out
}

/// Memory units a program takes in the robot computer (seed 001 §4.1.2).
pub fn program_units(instructions: &[Instruction]) -> u32 {
    instructions
        .iter()
        .map(|i| match i {
            Instruction::Position(_) => POSITION_UNITS,
            Instruction::Control(_) => CONTROL_UNITS,
        })
        .sum()
}

impl Batch {
    /// The pre-run check (every file as the plan checks it: conversion to the devices' units and
    /// ranges, reach, memory) and the batch it makes. Nothing is sent.
    pub fn new(
        items: Vec<Item>,
        mode: RunMode,
        job_id: String,
        drive: Drive,
        reach: Reach,
    ) -> Result<Batch, Error> {
        let setup = transfer::IndexerSetup {
            drive,
            start_velocity_command: true,
        };
        let prepared = items
            .iter()
            .map(|item| Prepared::of(item, mode, &setup, &reach).map_err(|e| item.refusal(e)))
            .collect::<Result<Vec<_>, Error>>()?;
        if mode != RunMode::Discrete {
            check_memory(&items, &prepared)?;
        }
        Ok(Batch {
            items,
            mode,
            job_id,
            drive,
            prepared,
        })
    }
}

impl Prepared {
    /// One item checked and converted for `mode`.
    fn of(
        item: &Item,
        mode: RunMode,
        setup: &transfer::IndexerSetup,
        reach: &Reach,
    ) -> Result<Prepared, Error> {
        // Continuous mode's timing is a property of the plan (every segment at least the
        // robot's time per instruction): files planned for another movement are refused.
        if mode == RunMode::Continuous && item.rob.header.movement != Movement::Continuous {
            return Err(Error::NotPlannedForContinuous {
                movement: item.rob.header.movement.keyword(),
            });
        }
        let mut rob = item.rob.clone();
        rob.header.movement = mode.movement();
        // The header's speeds go to the robot in every mode (discrete too, before its first
        // immediate move).
        transfer::speeds(&rob.header)?;
        let immediate: Vec<Positioning> = transfer::immediate_moves(&rob)?
            .into_iter()
            .filter_map(|c| match c {
                asea_protocol::Command::MoveImmediate(p) => Some(p),
                _ => None,
            })
            .collect();
        let mut targets_mm = Vec::with_capacity(rob.instructions.len());
        let mut cumulative_steps = vec![0i64];
        let mut mandrel = Vec::new();
        for (i, p) in rob.instructions.iter().zip(&immediate) {
            if i.reference != Reference::Absolute {
                return Err(Error::RelativePosition {
                    instruction: i.number,
                });
            }
            let t = p.pose.xyz_mm();
            if !reach.holds(t) {
                return Err(Error::OutOfReach {
                    instruction: i.number,
                    eye_mm: t,
                    radius_mm: (reach.min_radius_mm, reach.max_radius_mm),
                    height_mm: reach.z_range_mm,
                });
            }
            if !reach.arm_takes(t, p.pose.q.wxyz()) {
                return Err(Error::ArmCannotTake {
                    instruction: i.number,
                    eye_mm: t,
                });
            }
            transfer::indexer_move(&i.mandrel, setup, Some(i.number))?;
            targets_mm.push(t);
            mandrel.push(i.mandrel);
            let last = cumulative_steps.last().copied().unwrap_or(0);
            cumulative_steps.push(last + i.mandrel.steps);
        }
        if targets_mm.is_empty() {
            return Err(Error::EmptyProgram);
        }
        let program = if mode == RunMode::Discrete {
            // A discrete run sends the .ROB's moves, but a .IND beside it is the operator's file
            // too: one the indexer could not take is refused, not ignored.
            if let Some(ind) = &item.ind {
                transfer::indexer_program(ind, setup)?;
            }
            None
        } else {
            let total = cumulative_steps.last().copied().unwrap_or(0);
            Some(stored_program(item, &rob, mode, setup, total)?)
        };
        Ok(Prepared {
            targets_mm,
            immediate,
            mandrel,
            cumulative_steps,
            program,
        })
    }
}

/// The stored program of a program-mode item, its `.IND` checked against the `.ROB`'s `total`
/// steps.
fn stored_program(
    item: &Item,
    rob: &RobotFile,
    mode: RunMode,
    setup: &transfer::IndexerSetup,
    total: i64,
) -> Result<Vec<Instruction>, Error> {
    let ind = item.ind.as_ref().ok_or_else(|| Error::MissingFile {
        file: format!("{}.IND", item.name).into(),
        why: "program mode needs it",
    })?;
    transfer::indexer_program(ind, setup)?;
    if ind.path_move.steps != total {
        return Err(Error::MandrelSteps {
            ind_steps: ind.path_move.steps,
            rob_steps: total,
        });
    }
    let positions = transfer::robot_program(rob)?.instructions;
    Ok(handshake_program(
        &positions
            .iter()
            .filter(|i| matches!(i, Instruction::Position(_)))
            .skip(mode.points_before_program())
            .copied()
            .collect::<Vec<_>>(),
    ))
}

/// The batch's distinct programs in the robot's memory, with room for a resumed program as long
/// as the longest path (seed 001 §4.1.2).
fn check_memory(items: &[Item], prepared: &[Prepared]) -> Result<(), Error> {
    let mut seen: Vec<u8> = Vec::new();
    let mut units = 0u32;
    for (item, prep) in items.iter().zip(prepared) {
        let program = item.rob.header.program;
        if let Some(list) = &prep.program
            && !seen.contains(&program)
        {
            seen.push(program);
            units += program_units(list);
        }
    }
    let longest = prepared
        .iter()
        .filter_map(|p| p.program.as_ref())
        .map(|p| program_units(p))
        .max()
        .unwrap_or(0);
    if units + longest > MEMORY_UNITS {
        return Err(Error::BatchMemory {
            programs_units: units,
            programs: seen.len(),
            reserve_units: longest,
            capacity_units: MEMORY_UNITS,
        });
    }
    Ok(())
}
