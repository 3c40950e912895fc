//! A simulated cell busy with both devices: the robot running a stored program of vertical
//! 300 mm strokes, the mandrel turning continuously. Shared by `tests/simcell_events.rs` and
//! `benches/cell_hour.rs` (included with `#[path]`).

use std::time::Duration;

use asea_protocol::client::store_command;
use asea_protocol::command::{Control, Instruction};
use asea_protocol::frame::Frame;
use asea_protocol::link::Peer as _;
use asea_protocol::{Command, Flags, FrameConfig, Pose, Positioning, Speed, Zone};
use cell::run::device::Timebase as _;
use cell::sim::{Observer, SimCell, SimCellConfig};
use mandrel_drive::sim::Frontend as _;

/// A frame of `cmd` as the robot computer receives it.
fn frame(cmd: &Command) -> Frame {
    let bytes = cmd.encode(&FrameConfig::default()).unwrap();
    Frame {
        code: bytes[1],
        data: bytes[3..bytes.len() - 2].to_vec(),
    }
}

/// A cell whose robot, homed, runs a stored program of `points` strokes between heights 800 and
/// 500 mm at `speed_m_s` (fine zone), and whose mandrel turns continuously at 0.5 motor rev/s,
/// both started at cell time 4 s. With `ticked`, an observer is attached: the cell is then
/// polled every `simcell::TICK`.
pub fn stroking_cell(points: u16, speed_m_s: f64, ticked: bool) -> SimCell {
    let cell = SimCell::new(&SimCellConfig::default());
    cell.with(|p| {
        if ticked {
            p.observer = Some(Observer(Box::new(|_| {})));
        }
        let m = &mut p.robot.machine;
        for n in 1..=points {
            let z = if n % 2 == 0 { 500.0 } else { 800.0 };
            let i = Instruction::Position(Positioning {
                flags: Flags {
                    zone: Zone::Fine,
                    ..Flags::default()
                },
                pose: Pose::from_mm([900.0, 0.0, z], [1.0, 0.0, 0.0, 0.0]).unwrap(),
                speed: Speed::from_value("speed", speed_m_s).unwrap(),
            });
            m.execute(&frame(&store_command(1, n, &i)), 0.0);
        }
        m.execute(
            &frame(&store_command(1, points + 1, &Control::End.into())),
            0.0,
        );
        m.execute(&frame(&Command::Operate), 0.0);
        m.execute(&frame(&Command::SyncHome), 0.0);
        assert_eq!(m.last_error(), 0);
    })
    .unwrap();
    let t = cell.timebase();
    t.sleep(Duration::from_secs(4));
    let now = t.now_s();
    cell.with(|p| {
        p.robot
            .machine
            .execute(&frame(&Command::RunProgram { program: 1 }), now);
        assert_eq!(p.robot.machine.last_error(), 0);
        // As a RUN telegram's arrival does: the log's watch sees the program start.
        p.poll(Duration::from_secs_f64(now));
        p.card.receive(b"1A10 1MC 1H+ 1V0.5 1G\r", now);
    })
    .unwrap();
    cell
}
