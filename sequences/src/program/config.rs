//! The vendors' configuration data of a target, computed from the controller's joint angles and
//! the arm's configuration (`paths::arm::Config`: the wrist centre's side of axis 1, the elbow
//! bend, the wrist solution).
//!
//! - ABB `confdata [cf1, cf4, cf6, cfx]` (RAPID reference, data type `confdata`, for a 6-axis
//!   serial arm): `cf1`, `cf4`, `cf6` the quadrant of axes 1, 4 and 6, `floor(angle / 90°)`
//!   (quadrant 0 = 0°…90°, −1 = −90°…0°); `cfx` 0–7 the robot configuration: + 4 when the
//!   wrist centre is behind axis 1, + 2 when it is behind the lower arm (elbow down), + 1 when
//!   axis 5 is negative.
//! - KUKA `S` (Status) and `T` (Turn) of `E6POS` (KSS 8 programming manual, "Status and Turn"):
//!   S bit 0 set when the wrist root point lies in the overhead area (−X of the A1 coordinate
//!   system, i.e. behind axis 1), bit 1 set when A3 ≥ φ (the A3 angle at which the wrist root
//!   point lies on the line A2–A3 extended: elbow up), bit 2 set when A5 ≤ 0; T bit i set when
//!   axis i + 1 is negative.
//! - FANUC `CONFIG : 'F/N U/D T/B, t1, t4, t6'` (R-30iB HandlingTool operator's manual,
//!   "Position data"): `F` flip / `N` no flip (the wrist solution), `U` up / `D` down (the
//!   elbow), `T` front ("toward") / `B` back (the wrist centre's side of axis 1), and the turn
//!   numbers of J1, J4, J6: `t = floor((J + 180°)/360°)`, 0 for J in [−180°, 180°).

use paths::arm::{Elbow, Joints6, Shoulder, SixAxisArm, Wrist};

/// ABB `confdata`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AbbConf {
    /// Quadrant of axis 1.
    pub cf1: i32,
    /// Quadrant of axis 4.
    pub cf4: i32,
    /// Quadrant of axis 6.
    pub cf6: i32,
    /// The robot configuration, 0–7.
    pub cfx: i32,
}

/// KUKA Status and Turn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KukaStatus {
    /// `S`, bits 0–2.
    pub s: u8,
    /// `T`, bits 0–5.
    pub t: u8,
}

/// FANUC configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FanucConfig {
    /// `F` (true) or `N`.
    pub flip: bool,
    /// `U` (true) or `D`.
    pub up: bool,
    /// `T` (true) or `B`.
    pub front: bool,
    /// Turn numbers of J1, J4, J6.
    pub turns: [i32; 3],
}

impl FanucConfig {
    /// `F U T, 0, 0, 0` as the /POS section writes it.
    pub fn text(&self) -> String {
        format!(
            "{} {} {}, {}, {}, {}",
            if self.flip { 'F' } else { 'N' },
            if self.up { 'U' } else { 'D' },
            if self.front { 'T' } else { 'B' },
            self.turns[0],
            self.turns[1],
            self.turns[2]
        )
    }
}

fn radians(joints_deg: &[f64; 6]) -> Joints6 {
    joints_deg.map(f64::to_radians)
}

/// The quadrant `floor(angle / 90°)`, with a hair of tolerance so that an angle printed as
/// exactly 90° does not change quadrant by rounding.
fn quadrant(angle_deg: f64) -> i32 {
    ((angle_deg + 1e-9) / 90.0).floor() as i32
}

/// ABB `confdata` of the joints.
pub fn abb_conf(arm: &SixAxisArm, joints_deg: &[f64; 6]) -> AbbConf {
    let c = arm.kind.config_of(&radians(joints_deg));
    let cfx = i32::from(c.shoulder == Shoulder::Back) * 4
        + i32::from(c.elbow == Elbow::Down) * 2
        + i32::from(joints_deg[4] < 0.0);
    AbbConf {
        cf1: quadrant(joints_deg[0]),
        cf4: quadrant(joints_deg[3]),
        cf6: quadrant(joints_deg[5]),
        cfx,
    }
}

/// KUKA Status and Turn of the joints.
pub fn kuka_status(arm: &SixAxisArm, joints_deg: &[f64; 6]) -> KukaStatus {
    let c = arm.kind.config_of(&radians(joints_deg));
    let s = u8::from(c.shoulder == Shoulder::Back)
        + u8::from(c.elbow == Elbow::Up) * 2
        + u8::from(joints_deg[4] <= 0.0) * 4;
    let mut t = 0;
    for (i, j) in joints_deg.iter().enumerate() {
        if *j < 0.0 {
            t |= 1 << i;
        }
    }
    KukaStatus { s, t }
}

/// The FANUC turn number of a joint angle.
pub fn fanuc_turn(angle_deg: f64) -> i32 {
    ((angle_deg + 180.0) / 360.0).floor() as i32
}

/// FANUC configuration of the joints.
pub fn fanuc_config(arm: &SixAxisArm, joints_deg: &[f64; 6]) -> FanucConfig {
    let c = arm.kind.config_of(&radians(joints_deg));
    FanucConfig {
        flip: c.wrist == Wrist::Flip,
        up: c.elbow == Elbow::Up,
        front: c.shoulder == Shoulder::Front,
        turns: [
            fanuc_turn(joints_deg[0]),
            fanuc_turn(joints_deg[3]),
            fanuc_turn(joints_deg[5]),
        ],
    }
}
