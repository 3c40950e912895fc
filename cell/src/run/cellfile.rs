//! The cell description a run uses (docs/file-formats.md, "Cell file"): serial ports (none: the
//! simulated cell), the mandrel drive's gearing, the sync lines. It comes from the job's `[cell]`
//! or from `--cell CELL.toml`, which wins.

use std::path::Path;

use mandrel_drive::Drive;
use paths::Gearing;
use serde::Deserialize;
use toml::Spanned;

use crate::Error;
use crate::error::CellProblem;

/// `CELL.toml`.
#[derive(Debug, Clone, PartialEq, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct CellFile {
    /// A name for the operator.
    #[serde(default)]
    pub name: Option<String>,
    /// Serial ports; none named: the simulated cell.
    #[serde(default)]
    pub ports: PortsSection,
    /// The mandrel drive.
    #[serde(default)]
    pub drive: Option<DriveSection>,
    /// Opto-isolator delay of the simulated sync lines, s.
    #[serde(default)]
    pub opto_delay_s: Option<Spanned<f64>>,
    /// Calibration tolerances (`windcell predict`'s setup Monte Carlo).
    #[serde(default)]
    pub tolerance: Option<ToleranceSection>,
    /// A six-axis arm's controller I/O for the sync lines of a decoupled mandrel.
    #[serde(default)]
    pub robot_io: Option<RobotIoSection>,
    /// The indexer's command language.
    #[serde(default)]
    pub indexer: Option<IndexerSection>,
}

/// `[indexer]`: the command language the indexer on the indexer port speaks.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IndexerSection {
    /// `"x"` (the default) or `"grbl"`.
    pub dialect: Spanned<IndexerDialect>,
}

/// The indexer's command language (docs/mandrel-drive.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum IndexerDialect {
    /// Compumotor X-language (seed 001 §5.3.2): the thesis's indexer, triggered by the start line.
    #[default]
    X,
    /// GRBL 1.1 / grblHAL turning the mandrel as its A axis (`mandrel_drive::GrblClient`): no
    /// trigger input, so discrete mode only.
    Grbl,
}

impl IndexerDialect {
    /// The cell file's word for it.
    pub fn keyword(self) -> &'static str {
        match self {
            IndexerDialect::X => "x",
            IndexerDialect::Grbl => "grbl",
        }
    }
}

/// `[robot_io]`: the robot controller's digital signals that carry the sync lines when a
/// six-axis arm's own program winds beside windcell's indexer (`docs/robot-programs.md`).
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotIoSection {
    /// The robot's digital output that starts the indexer's segment (1–4096).
    pub start_output: Spanned<u16>,
    /// The robot's digital input the indexer raises when the mandrel is in position (1–4096).
    pub in_position_input: Spanned<u16>,
}

/// `[tolerance]`: half-widths of how far the true cell may lie from its calibration; absent
/// fields take the thesis cell's figures ([`Tolerances::default`]).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToleranceSection {
    /// Rotation axis position `[x, y]`, mm.
    pub axis_offset_mm: Option<Spanned<[f64; 2]>>,
    /// Rotation axis lean toward `+x` and `+y`, degrees.
    pub axis_tilt_deg: Option<Spanned<[f64; 2]>>,
    /// The drive's zero angle, degrees.
    pub zero_angle_deg: Option<Spanned<f64>>,
    /// The mandrel's diameter, mm.
    pub diameter_mm: Option<Spanned<f64>>,
}

/// `[ports]`.
#[derive(Debug, Clone, PartialEq, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct PortsSection {
    /// The robot computer's link.
    pub robot: Option<Spanned<String>>,
    /// The indexer's link.
    pub indexer: Option<Spanned<String>>,
    /// The port whose modem-control pins carry the sync lines (RTS start out, CTS in position
    /// in, DSR e-stop in; docs/hardware.md).
    pub sync: Option<Spanned<String>>,
}

/// `[drive]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveSection {
    /// Motor steps per motor revolution.
    pub steps_per_rev: Spanned<u32>,
    /// `[motor pulley teeth, mandrel pulley teeth]`.
    pub gear_ratio: Spanned<[u32; 2]>,
}

/// Where the devices are.
#[derive(Debug, Clone, PartialEq)]
pub enum Devices {
    /// The simulated cell, in process.
    Simulated,
    /// Serial ports.
    Serial {
        /// Robot port.
        robot: String,
        /// Indexer port.
        indexer: String,
        /// Sync-line port (none: discrete mode only).
        sync: Option<String>,
    },
}

/// The sync signals of a six-axis arm's controller when the cell file names none: digital
/// output 1 and input 1.
pub const DEFAULT_ROBOT_IO: sequences::program::SyncSignals = sequences::program::SyncSignals {
    start_output: 1,
    in_position_input: 1,
};

/// The cell as a run uses it.
#[derive(Debug, Clone, PartialEq)]
pub struct Cell {
    /// Where the description came from (`--cell FILE`, or the job).
    pub source: String,
    /// The devices.
    pub devices: Devices,
    /// The drive.
    pub drive: Drive,
    /// Opto delay of the simulated lines, s.
    pub opto_delay_s: f64,
    /// The arm the simulated robot checks every pose against (the job's `[cell.robot]` and eye
    /// mechanism; `paths::robot::Arm::default()` for a cell file or the built-in cell).
    pub arm: paths::robot::Arm,
    /// Calibration tolerances.
    pub tolerances: Tolerances,
    /// A six-axis arm's sync signals (`[robot_io]`, default output 1 and input 1).
    pub robot_io: sequences::program::SyncSignals,
    /// The indexer's command language (`[indexer] dialect`, X by default).
    pub dialect: IndexerDialect,
    /// Where the cell file names the dialect (1-based line and column), for refusals that
    /// depend on the run (a program mode the dialect cannot drive).
    pub dialect_place: Option<(usize, usize)>,
}

fn drive_of(steps_per_rev: u32, [motor, mandrel]: [u32; 2]) -> Result<Drive, CellProblem> {
    Drive::new(
        Gearing {
            steps_per_motor_rev: steps_per_rev,
            motor_teeth: motor,
            mandrel_teeth: mandrel,
        },
        mandrel_drive::units::TRANSLATOR_LIMIT_PPS,
    )
    .map_err(CellProblem::Drive)
}

fn devices_of(
    robot: Option<&String>,
    indexer: Option<&String>,
    sync: Option<&String>,
) -> Result<Devices, CellProblem> {
    match (robot, indexer, sync) {
        (None, None, None) => Ok(Devices::Simulated),
        (Some(r), Some(i), s) => Ok(Devices::Serial {
            robot: r.clone(),
            indexer: i.clone(),
            sync: s.cloned(),
        }),
        _ => Err(CellProblem::Ports),
    }
}

impl Cell {
    /// The cell of a job file's `[cell]`.
    pub fn of_job(job: &sequences::Job, file: &Path) -> Result<Cell, Error> {
        let c = &job.cell;
        let bad = |problem| Error::Cell {
            file: file.to_path_buf(),
            place: None,
            problem,
        };
        let drive = drive_of(
            *c.drive.steps_per_rev.get_ref(),
            *c.drive.gear_ratio.get_ref(),
        )
        .map_err(bad)?;
        let devices = devices_of(
            c.ports.robot.as_ref(),
            c.ports.indexer.as_ref(),
            c.ports.sync.as_ref(),
        )
        .map_err(bad)?;
        Ok(Cell {
            source: format!("{} [cell]", file.display()),
            devices,
            drive,
            opto_delay_s: mandrel_drive::sync::OPTO_DELAY_S,
            arm: crate::plan::tool::arm(job),
            tolerances: Tolerances::default(),
            robot_io: DEFAULT_ROBOT_IO,
            dialect: IndexerDialect::X,
            dialect_place: None,
        })
    }

    /// The simulated cell with the thesis drive (a sequence run without `--cell`).
    pub fn simulated() -> Cell {
        Cell {
            source: "the built-in simulated cell".into(),
            devices: Devices::Simulated,
            drive: Drive::default(),
            opto_delay_s: mandrel_drive::sync::OPTO_DELAY_S,
            arm: paths::robot::Arm::default(),
            tolerances: Tolerances::default(),
            robot_io: DEFAULT_ROBOT_IO,
            dialect: IndexerDialect::X,
            dialect_place: None,
        }
    }

    /// Reads `CELL.toml`; errors name the file, line and column.
    pub fn load(path: &Path) -> Result<Cell, Error> {
        let text = sequences::source::read_text(path, sequences::source::MAX_JOB_BYTES)?;
        Cell::parse(&text, path)
    }

    /// Parses the text of a cell file read from `path`.
    pub fn parse(text: &str, path: &Path) -> Result<Cell, Error> {
        let at = |offset: usize, problem| Error::Cell {
            file: path.to_path_buf(),
            place: Some(sequences::error::line_column(text, offset)),
            problem,
        };
        let file: CellFile = toml::from_str(text).map_err(|e| {
            let (offset, message) = sequences::error::toml_refusal(&e);
            at(offset, CellProblem::Syntax(message))
        })?;
        // Each refusal is placed at the value at fault (its own span in the text).
        let drive = match &file.drive {
            Some(d) => {
                let span = if *d.steps_per_rev.get_ref() == 0 {
                    d.steps_per_rev.span()
                } else {
                    d.gear_ratio.span()
                };
                drive_of(*d.steps_per_rev.get_ref(), *d.gear_ratio.get_ref())
                    .map_err(|m| at(span.start, m))?
            }
            None => Drive::default(),
        };
        let ports = &file.ports;
        let devices = devices_of(
            ports.robot.as_ref().map(Spanned::get_ref),
            ports.indexer.as_ref().map(Spanned::get_ref),
            ports.sync.as_ref().map(Spanned::get_ref),
        )
        .map_err(|m| {
            // Ports half named: the first one given, whose partner is missing.
            let given = [&ports.robot, &ports.indexer, &ports.sync]
                .into_iter()
                .flatten()
                .next();
            at(given.map_or(0, |p| p.span().start), m)
        })?;
        let opto_delay_s = match &file.opto_delay_s {
            Some(v) if !(0.0..=1.0).contains(v.get_ref()) => {
                return Err(at(
                    v.span().start,
                    CellProblem::OptoDelay {
                        value_s: *v.get_ref(),
                    },
                ));
            }
            Some(v) => *v.get_ref(),
            None => mandrel_drive::sync::OPTO_DELAY_S,
        };
        let tolerances = match &file.tolerance {
            Some(t) => tolerances_of(t).map_err(|offset| at(offset, CellProblem::Tolerance))?,
            None => Tolerances::default(),
        };
        let robot_io = match &file.robot_io {
            Some(io) => {
                for v in [&io.start_output, &io.in_position_input] {
                    if !(1..=4096).contains(v.get_ref()) {
                        return Err(at(
                            v.span().start,
                            CellProblem::RobotIoSignal {
                                signal: *v.get_ref(),
                            },
                        ));
                    }
                }
                sequences::program::SyncSignals {
                    start_output: *io.start_output.get_ref(),
                    in_position_input: *io.in_position_input.get_ref(),
                }
            }
            None => DEFAULT_ROBOT_IO,
        };
        let dialect_value = file.indexer.as_ref().map(|i| &i.dialect);
        let dialect = dialect_value.map_or(IndexerDialect::X, |d| *d.get_ref());
        let dialect_at = dialect_value.map(|d| d.span().start);
        if dialect == IndexerDialect::Grbl && devices == Devices::Simulated {
            return Err(at(
                dialect_at.unwrap_or(0),
                CellProblem::SimulatedDialect {
                    dialect: dialect.keyword(),
                },
            ));
        }
        Ok(Cell {
            source: path.display().to_string(),
            devices,
            drive,
            opto_delay_s,
            arm: paths::robot::Arm::default(),
            tolerances,
            robot_io,
            dialect,
            dialect_place: dialect_at.map(|o| sequences::error::line_column(text, o)),
        })
    }
}

/// The `[tolerance]` table's figures over the defaults; a figure that is not finite or not within
/// 0–100 is refused at its byte offset.
fn tolerances_of(t: &ToleranceSection) -> Result<Tolerances, usize> {
    let pair = |v: &Option<Spanned<[f64; 2]>>| v.as_ref().map(|v| (*v.get_ref(), v.span().start));
    let one = |v: &Option<Spanned<f64>>| v.as_ref().map(|v| (*v.get_ref(), v.span().start));
    let (offset, tilt, zero, diameter) = (
        pair(&t.axis_offset_mm),
        pair(&t.axis_tilt_deg),
        one(&t.zero_angle_deg),
        one(&t.diameter_mm),
    );
    let figures = offset
        .iter()
        .chain(&tilt)
        .flat_map(|&([a, b], at)| [(a, at), (b, at)])
        .chain(zero.iter().chain(&diameter).copied());
    for (v, at) in figures {
        if !(v.is_finite() && (0.0..=100.0).contains(&v)) {
            return Err(at);
        }
    }
    let mut tolerances = Tolerances::default();
    if let Some((v, _)) = offset {
        tolerances.axis_offset_mm = v;
    }
    if let Some((v, _)) = tilt {
        tolerances.axis_tilt_rad = v.map(f64::to_radians);
    }
    if let Some((v, _)) = zero {
        tolerances.zero_angle_rad = v.to_radians();
    }
    if let Some((v, _)) = diameter {
        tolerances.diameter_mm = v;
    }
    Ok(tolerances)
}

/// Calibration tolerances of the cell: each figure is the half-width of a uniform distribution
/// the Monte Carlo draws the true cell's deviation from (docs/file-formats.md, "Cell file").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerances {
    /// Rotation axis position, cell frame `[x, y]`, mm.
    pub axis_offset_mm: [f64; 2],
    /// Rotation axis lean toward `+x` and `+y`, rad.
    pub axis_tilt_rad: [f64; 2],
    /// Where the drive's zero lies, rad.
    pub zero_angle_rad: f64,
    /// Mandrel diameter, mm.
    pub diameter_mm: f64,
}

impl Default for Tolerances {
    /// The thesis's cell (seed 001 §6.2.1 item 2, §6.1, §6.4.1): the drive axis found 0.1 mm
    /// (x–z) and 0.15 mm (y–z) out along the 178 mm mandrel, the mandrel repeatable within 0.2°,
    /// the cylinder's diameter ±0.05 mm.
    fn default() -> Self {
        Tolerances {
            axis_offset_mm: [0.1, 0.15],
            axis_tilt_rad: [(0.1f64 / 178.0).atan(), (0.15f64 / 178.0).atan()],
            zero_angle_rad: 0.2f64.to_radians(),
            diameter_mm: 0.05,
        }
    }
}

impl Tolerances {
    /// Every figure multiplied by `k`.
    pub fn scaled(&self, k: f64) -> Tolerances {
        Tolerances {
            axis_offset_mm: self.axis_offset_mm.map(|v| v * k),
            axis_tilt_rad: self.axis_tilt_rad.map(|v| v * k),
            zero_angle_rad: self.zero_angle_rad * k,
            diameter_mm: self.diameter_mm * k,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simulated_and_serial_cells_parse_and_half_named_ports_are_refused() {
        let p = Path::new("C.toml");
        let c = Cell::parse(
            "name = \"sim\"\n[drive]\nsteps_per_rev = 400\ngear_ratio = [13, 60]\n",
            p,
        )
        .unwrap();
        assert_eq!(c.devices, Devices::Simulated);
        assert_eq!(c.drive, Drive::default());
        let c = Cell::parse(
            "[ports]\nrobot = \"/dev/ttyS0\"\nindexer = \"/dev/ttyS1\"\nsync = \"/dev/ttyS0\"\n",
            p,
        )
        .unwrap();
        assert!(matches!(c.devices, Devices::Serial { .. }));
        let e = Cell::parse("\n[ports]\nrobot = \"/dev/ttyS0\"\n", p).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("C.toml:3:9: name the robot and indexer ports"),
            "{e}"
        );
        let e = Cell::parse("[drive]\nsteps = 400\n", p).unwrap_err();
        assert!(e.to_string().starts_with("C.toml:2:1:"), "{e}");
        assert!(e.is_input());
    }

    /// `[indexer] dialect`: X by default, `grbl` with ports (its value's place kept for the run's
    /// refusals), refused without ports (the built-in cell speaks the X-language) and for any
    /// other word, each at the value's line and column.
    #[test]
    fn the_indexer_dialect_is_read_and_refused_at_its_value() {
        let p = Path::new("C.toml");
        let ports = "[ports]\nrobot = \"/dev/ttyS0\"\nindexer = \"/dev/ttyS1\"\n";
        let c = Cell::parse(ports, p).unwrap();
        assert_eq!((c.dialect, c.dialect_place), (IndexerDialect::X, None));
        let c = Cell::parse(&format!("{ports}\n[indexer]\ndialect = \"grbl\"\n"), p).unwrap();
        assert_eq!(c.dialect, IndexerDialect::Grbl);
        assert_eq!(c.dialect_place, Some((6, 11)));
        let c = Cell::parse(&format!("{ports}[indexer]\ndialect = \"x\"\n"), p).unwrap();
        assert_eq!(c.dialect, IndexerDialect::X);
        let e = Cell::parse("[indexer]\ndialect =  \"grbl\"\n", p).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("C.toml:2:12: [indexer] dialect = \"grbl\""),
            "{e}"
        );
        assert!(e.is_input());
        let e = Cell::parse(&format!("{ports}[indexer]\ndialect = \"gcode\"\n"), p).unwrap_err();
        assert!(e.to_string().starts_with("C.toml:5:11:"), "{e}");
        assert!(e.is_input());
        let e = Cell::parse(&format!("{ports}[indexer]\nlanguage = \"x\"\n"), p).unwrap_err();
        assert!(e.to_string().starts_with("C.toml:5:1:"), "{e}");
    }

    #[test]
    fn the_example_cell_files_parse() {
        let sim = Cell::parse(
            include_str!("../../../examples/cell-sim.toml"),
            Path::new("s"),
        )
        .unwrap();
        assert_eq!(sim.devices, Devices::Simulated);
        assert_eq!(sim.opto_delay_s, 20e-6);
        let serial = Cell::parse(
            include_str!("../../../examples/cell-serial.toml"),
            Path::new("r"),
        )
        .unwrap();
        assert_eq!(
            serial.devices,
            Devices::Serial {
                robot: "/dev/ttyS0".into(),
                indexer: "/dev/ttyS1".into(),
                sync: Some("/dev/ttyS0".into())
            }
        );
    }
}
