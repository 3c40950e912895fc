//! The layout of a stored winding program in the robot computer's memory (seed 001 §4.1.2,
//! §5.6.4, App. D): the control instructions windcell stores around a path's positionings, and
//! how many positionings fit beside them. `plan` refuses a path that does not fit;
//! `run::transfer` builds the program to this layout.

use asea_protocol::command::{CONTROL_UNITS, MEMORY_UNITS, POSITION_UNITS};

/// Control instructions stored ahead of the first point: lower "in position", wait for start.
pub const PROLOGUE_LEN: u16 = 2;

/// Control instructions a stored program adds to its positionings: the start handshake
/// ([`PROLOGUE_LEN`]: "in position" low, wait for the start input), then "in position" and `End`
/// (`crate::run::transfer::robot_program`).
pub const PROGRAM_CONTROL_INSTRUCTIONS: usize = PROLOGUE_LEN as usize + 2;

/// The most positioning instructions one stored program can hold beside its
/// [`PROGRAM_CONTROL_INSTRUCTIONS`] in the robot's memory (seed 001 §4.1.2: 470 positioning, or
/// 300 positioning and 200 control; the simulator's units): 466.
pub fn max_positioning_instructions() -> usize {
    let control = PROGRAM_CONTROL_INSTRUCTIONS as u32 * CONTROL_UNITS;
    ((MEMORY_UNITS - control) / POSITION_UNITS) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_thesis_memory_holds_466_positionings_beside_the_handshake() {
        // §4.1.2: 470 positionings fill the memory; the 4 control instructions take 68 units,
        // 3.4 positionings' worth, so 466 whole positionings remain.
        assert_eq!(PROGRAM_CONTROL_INSTRUCTIONS, 4);
        assert_eq!(max_positioning_instructions(), 466);
    }
}
