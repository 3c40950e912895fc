//! Universal Robots URScript (`.script`), after "The URScript Programming Language" manual for
//! e-Series (`def … end`, `movel`, `movej`, poses `p[x, y, z, rx, ry, rz]` in metres with a
//! rotation vector in radians, `pose_trans`, `set_tcp`, `set_standard_digital_out`,
//! `get_standard_digital_in`, `sync`).
//!
//! # What is written
//! One program `def name(): … end` (a UR controller runs a script of any length sent to it,
//! so the program is never split):
//! - `set_tcp(p[…])` the eye on the flange and `wc_work = p[…]` the work frame in the base frame;
//! - each target `pose_trans(wc_work, p[x, y, z, rx, ry, rz])`: metres with 7 decimals (0.1 µm)
//!   and the rotation vector (axis × angle, the angle in [0, π]) in radians with 7 decimals;
//! - the first target `movej(…, a=1.4, v=0.5)` (joint move to the start, inverse kinematics on
//!   the controller), every other `movel(…, a=1.2, v=…, t=…, r=…)`: `v` the segment's speed in
//!   m/s, `t` its time in s (the manual: "t: time [S]", which sets the move's duration), `r` the
//!   blend radius in m, left out for a stop point. `a = 1.2` m/s² is UR's default tool
//!   acceleration.
//! - Sync at a target: `set_standard_digital_out(n, True)` before the move,
//!   `while not get_standard_digital_in(m): sync() end`, `set_standard_digital_out(n, False)`,
//!   `while get_standard_digital_in(m): sync() end` after it.
//!
//! A coupled mandrel is refused by [`super::write`] (a UR controller has no external axes).

use std::fmt::Write as _;

use super::lex::{Cursor, Kind, Tok, lex};
use super::{
    ConfigData, Frame, Item, MandrelCoupling, Motion, ProgramPath, ReadTarget, Routine, Step, Unit,
    Zone, fixed, identifier, quaternion_rotation_vector, rotation_vector_quaternion,
};
use crate::Error;

fn pose_text(f: &Frame) -> String {
    let r = quaternion_rotation_vector(f.orientation);
    format!(
        "p[{}, {}, {}, {}, {}, {}]",
        fixed(f.position_mm[0] / 1000.0, 7),
        fixed(f.position_mm[1] / 1000.0, 7),
        fixed(f.position_mm[2] / 1000.0, 7),
        fixed(r[0], 7),
        fixed(r[1], 7),
        fixed(r[2], 7)
    )
}

/// The one program file.
pub(crate) fn write(path: &ProgramPath) -> Result<Vec<(String, String)>, Error> {
    let id = identifier(super::Format::UrScript, &path.name);
    let MandrelCoupling::Decoupled { sync } = path.mandrel else {
        return Err(Error::content(
            "a URScript program cannot drive a coupled mandrel",
        ));
    };
    let mut s = String::new();
    let _ = writeln!(s, "def {id}():");
    let _ = writeln!(
        s,
        "  # windcell path {}: {} targets",
        path.name.replace(['\n', '\r'], " "),
        path.targets.len()
    );
    let _ = writeln!(s, "  set_tcp({})", pose_text(&path.tool));
    let _ = writeln!(s, "  wc_work = {}", pose_text(&path.work));
    for (k, t) in path.targets.iter().enumerate() {
        let pose = format!(
            "pose_trans(wc_work, {})",
            pose_text(&Frame {
                position_mm: t.position_mm,
                orientation: t.orientation,
            })
        );
        if k == 0 {
            let _ = writeln!(s, "  movej({pose}, a=1.4, v=0.5)");
            continue;
        }
        let mut args = format!("a=1.2, v={}", fixed(t.speed_mm_s.max(0.001) / 1000.0, 6));
        if t.duration_s > 0.0 {
            let _ = write!(args, ", t={}", fixed(t.duration_s, 4));
        }
        if t.zone_mm > 0.0 && !t.sync {
            let _ = write!(args, ", r={}", fixed(t.zone_mm / 1000.0, 6));
        }
        if t.sync {
            let _ = writeln!(s, "  set_standard_digital_out({}, True)", sync.start_output);
            let _ = writeln!(s, "  movel({pose}, {args})");
            let _ = writeln!(
                s,
                "  while not get_standard_digital_in({}):\n    sync()\n  end",
                sync.in_position_input
            );
            let _ = writeln!(
                s,
                "  set_standard_digital_out({}, False)",
                sync.start_output
            );
            let _ = writeln!(
                s,
                "  while get_standard_digital_in({}):\n    sync()\n  end",
                sync.in_position_input
            );
        } else {
            let _ = writeln!(s, "  movel({pose}, {args})");
        }
    }
    let _ = writeln!(s, "end");
    Ok(vec![(format!("{id}.script"), s)])
}

// ---------------------------------------------------------------------------------------------
// Reading

/// Functions that change nothing the reader reports.
const IGNORED: &[&str] = &[
    "textmsg",
    "sync",
    "sleep",
    "set_payload",
    "set_target_payload",
    "set_tool_voltage",
    "set_gravity",
    "set_safety_mode_transition_hardness",
    "popup",
];

/// A pose `p[…]` in mm and a quaternion.
fn pose(c: &mut Cursor<'_>) -> Result<Frame, Error> {
    let t = c.peek();
    if !c.eat_ident("p") {
        return Err(t.error(format!("expected a pose p[…], found {}", t.shown())));
    }
    c.expect_punct("[")?;
    let mut v = [0.0; 6];
    for (i, x) in v.iter_mut().enumerate() {
        if i > 0 {
            c.expect_punct(",")?;
        }
        *x = c.number()?;
    }
    c.expect_punct("]")?;
    Ok(Frame {
        position_mm: [v[0] * 1000.0, v[1] * 1000.0, v[2] * 1000.0],
        orientation: rotation_vector_quaternion([v[3], v[4], v[5]]),
    })
}

fn skip_call(c: &mut Cursor<'_>) -> Result<(), Error> {
    let open = c.peek();
    c.expect_punct("(")?;
    let mut depth = 1;
    while depth > 0 {
        let t = c.next();
        match &t.kind {
            Kind::Newline => {
                return Err(open.error("the call's parenthesis is not closed on its line"));
            }
            Kind::Punct("(") => depth += 1,
            Kind::Punct(")") => depth -= 1,
            _ => {}
        }
    }
    Ok(())
}

/// Parses one script.
pub(crate) fn parse(text: &str) -> Result<Unit, Error> {
    let toks = lex(text, 1, Some('#'))?;
    let mut unit = Unit::default();
    let mut c = Cursor::new(&toks);
    let mut current: Option<Routine> = None;
    loop {
        c.skip_newlines();
        if c.at_end() {
            break;
        }
        let t = c.peek();
        let Some(routine) = current.as_mut() else {
            current = top_level(&mut c)?;
            continue;
        };
        let (word, _) = c
            .ident()
            .map_err(|_| t.error(format!("expected a statement, found {}", t.shown())))?;
        if word == "end" {
            c.newline()?;
            if let Some(r) = current.take() {
                unit.routines.push(r);
            }
            continue;
        }
        if let Some(item) = statement(&mut c, word, t, &mut unit)? {
            routine.body.push(item);
        }
    }
    if current.is_some() {
        return Err(Error::at(text.lines().count().max(1), 1, "end is missing"));
    }
    Ok(unit)
}

/// A line outside a definition: `def name():` opens a routine (returned); a top-level call of
/// the program (`name()`) after its definition is passed over.
fn top_level(c: &mut Cursor<'_>) -> Result<Option<Routine>, Error> {
    let t = c.peek();
    if !c.eat_ident("def") {
        c.ident()
            .map_err(|_| t.error(format!("expected def, found {}", t.shown())))?;
        c.expect_punct("(")?;
        c.expect_punct(")")?;
        c.newline()?;
        return Ok(None);
    }
    let (name, _) = c.ident()?;
    c.expect_punct("(")?;
    c.expect_punct(")")?;
    c.expect_punct(":")?;
    c.newline()?;
    Ok(Some(Routine {
        name,
        body: Vec::new(),
    }))
}

/// One statement of a routine body after its first word `word` (the token `t`): the item it adds
/// to the body, if any (`set_tcp` and the work frame go to `unit`).
fn statement(
    c: &mut Cursor<'_>,
    word: String,
    t: &Tok,
    unit: &mut Unit,
) -> Result<Option<Item>, Error> {
    match word.as_str() {
        "movel" | "movej" => return move_statement(c, &word, t).map(Some),
        "set_standard_digital_out" => return output_statement(c, t).map(Some),
        "while" => return wait_loop(c, t).map(Some),
        "set_tcp" => {
            c.expect_punct("(")?;
            let f = pose(c)?;
            c.expect_punct(")")?;
            c.newline()?;
            unit.tool.get_or_insert(f);
        }
        "global" | "wc_work" => {
            if word == "global" {
                let w = c.peek();
                if !c.eat_ident("wc_work") {
                    return Err(w.error(format!("expected wc_work, found {}", w.shown())));
                }
            }
            c.expect_punct("=")?;
            let f = pose(c)?;
            c.newline()?;
            unit.work.get_or_insert(f);
        }
        w if IGNORED.contains(&w) => {
            skip_call(c)?;
            c.newline()?;
        }
        _ => {
            if c.peek().is_punct("(") && c.peek_at(1).is_punct(")") {
                c.pos += 2;
                c.newline()?;
                return Ok(Some(Item::Call {
                    name: word,
                    line: t.line,
                    column: t.column,
                }));
            }
            return Err(t.error(format!(
                "statement {word} is not one a winding program uses"
            )));
        }
    }
    Ok(None)
}

/// `movel(…)` or `movej(…)` (`word`, at `t`) after its name: the target, in the work frame
/// (`pose_trans(wc_work, p[…])`) or as a bare pose.
fn move_statement(c: &mut Cursor<'_>, word: &str, t: &Tok) -> Result<Item, Error> {
    c.expect_punct("(")?;
    let frame = if c.eat_ident("pose_trans") {
        c.expect_punct("(")?;
        let w = c.peek();
        if !c.eat_ident("wc_work") {
            return Err(w.error(format!("expected wc_work, found {}", w.shown())));
        }
        c.expect_punct(",")?;
        let f = pose(c)?;
        c.expect_punct(")")?;
        f
    } else {
        pose(c)?
    };
    let (v, time, r) = move_arguments(c, word)?;
    c.expect_punct(")")?;
    c.newline()?;
    let linear = word == "movel";
    Ok(Item::Step(Step::Move(ReadTarget {
        file: String::new(),
        line: t.line,
        motion: if linear {
            Motion::Linear
        } else {
            Motion::Joint
        },
        position_mm: frame.position_mm,
        orientation: frame.orientation,
        config: ConfigData::None,
        external_deg: None,
        speed_mm_s: if linear { v.map(|x| x * 1000.0) } else { None },
        duration_s: time.filter(|x| *x > 0.0),
        zone: match r {
            Some(x) if x > 0.0 => Zone::Distance(x * 1000.0),
            _ => Zone::Fine,
        },
    })))
}

/// A move's `v` (m/s), `t` (s) and `r` (m), each as given.
type MoveArguments = (Option<f64>, Option<f64>, Option<f64>);

/// The named arguments of a move after its pose (`, a=…, v=…, t=…, r=…`); `a` is read and left.
fn move_arguments(c: &mut Cursor<'_>, word: &str) -> Result<MoveArguments, Error> {
    let (mut v, mut time, mut r) = (None, None, None);
    while c.eat_punct(",") {
        let (name, nt) = c.ident()?;
        c.expect_punct("=")?;
        let x = c.number()?;
        let slot = match name.as_str() {
            "a" => None,
            "v" => Some(&mut v),
            "t" => Some(&mut time),
            "r" => Some(&mut r),
            _ => return Err(nt.error(format!("{word} has no argument {name}"))),
        };
        if x < 0.0 {
            return Err(nt.error(format!("{name} must not be negative")));
        }
        if let Some(s) = slot {
            *s = Some(x);
        }
    }
    Ok((v, time, r))
}

/// `set_standard_digital_out(n, True|False)` (at `t`) after its name.
fn output_statement(c: &mut Cursor<'_>, t: &Tok) -> Result<Item, Error> {
    c.expect_punct("(")?;
    let n = c.integer()?;
    c.expect_punct(",")?;
    let b = c.peek();
    let on = if c.eat_ident("True") {
        true
    } else if c.eat_ident("False") {
        false
    } else {
        return Err(b.error(format!("expected True or False, found {}", b.shown())));
    };
    c.expect_punct(")")?;
    c.newline()?;
    Ok(Item::Step(Step::Output {
        file: String::new(),
        line: t.line,
        number: u16::try_from(n).map_err(|_| t.error("output number too large"))?,
        on,
    }))
}

/// The sync wait `while [not] get_standard_digital_in(n): sync() … end` (at `t`) after `while`.
fn wait_loop(c: &mut Cursor<'_>, t: &Tok) -> Result<Item, Error> {
    let on = c.eat_ident("not");
    let g = c.peek();
    if !c.eat_ident("get_standard_digital_in") {
        return Err(g.error("expected get_standard_digital_in (the sync wait)"));
    }
    c.expect_punct("(")?;
    let n = c.integer()?;
    c.expect_punct(")")?;
    c.expect_punct(":")?;
    c.newline()?;
    // The loop body: sync() or sleep(…) only, then `end`.
    loop {
        c.skip_newlines();
        let s = c.peek();
        if c.eat_ident("end") {
            c.newline()?;
            break;
        }
        if c.eat_ident("sync") || c.eat_ident("sleep") {
            skip_call(c)?;
            c.newline()?;
            continue;
        }
        return Err(s.error(format!(
            "expected sync() or end in the wait loop, found {}",
            s.shown()
        )));
    }
    Ok(Item::Step(Step::Wait {
        file: String::new(),
        line: t.line,
        number: u16::try_from(n).map_err(|_| t.error("input number too large"))?,
        on,
    }))
}
