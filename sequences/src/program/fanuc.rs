//! FANUC TP programs in their ASCII form (`.ls`), after the R-30iB HandlingTool operator's
//! manual (program structure `/PROG`, `/ATTR`, `/MN`, `/POS`, `/END`; motion `L P[n] …mm/sec
//! CNTn|FINE`; position data `UF`, `UT`, `CONFIG : 'F/N U/D T/B, t1, t4, t6'`, `X`, `Y`, `Z` in
//! mm and `W`, `P`, `R` in degrees; `DO[n]=ON`; `WAIT DI[n]=ON`; `CALL`).
//!
//! # What is written
//! - Each target `P[n]` in `/POS`: group 1, user frame 1 and tool frame 1, the configuration
//!   from the joints ([`super::config::fanuc_config`]), mm with 3 decimals and `W`, `P`, `R` the
//!   rotations about the fixed `x`, `y`, `z` axes in that order (`R = Rz(R)·Ry(P)·Rx(W)`) in
//!   degrees with 3 decimals. Coupled: the mandrel axis as the extended axis `E1` of group 1
//!   (degrees); the targets are in the mandrel frame, so user frame 1 must turn with E1 (a
//!   coordinated extended axis, FANUC's Coordinated Motion option).
//! - `/MN`: `UFRAME_NUM=1`, `UTOOL_NUM=1` (the frames' values as comments: set them on the
//!   controller), the first target `J P[1] 20% FINE`, every other `L P[n] Vmm/sec CNTk|FINE`:
//!   `V` the segment's speed in whole mm/sec (TP's linear speed unit), `k` the zone in mm
//!   rounded and capped at 100 (CNT is a 0–100 rounding level, not a distance: the mapping is
//!   windcell's, the one common offline programming uses), `FINE` for a stop point.
//! - Sync at a target (decoupled): `DO[n]=ON` before the move, the move `FINE`, `WAIT DI[m]=ON`,
//!   `DO[n]=OFF`, `WAIT DI[m]=OFF`.
//! - Split: at most [`TARGETS_PER_PROGRAM`] targets per program; the main program `CALL`s the
//!   parts in order.

use std::collections::HashMap;
use std::fmt::Write as _;

use paths::arm::SixAxisArm;

use super::config::{FanucConfig, fanuc_config};
use super::lex::{Cursor, Kind, Tok, lex};
use super::{
    ConfigData, Item, MandrelCoupling, Motion, ProgramPath, ReadTarget, Routine, Step, Unit, Zone,
    fixed, identifier, part_name, parts, quaternion_zyx_deg, zyx_deg_quaternion,
};
use crate::Error;

/// Targets per TP program before the program is split.
pub const TARGETS_PER_PROGRAM: usize = 1000;

fn header(name: &str, comment: &str, lines: usize) -> String {
    format!(
        "/PROG  {name}\n/ATTR\nOWNER\t\t= MNEDITOR;\nCOMMENT\t\t= \"{comment}\";\nPROG_SIZE\t= 0;\n\
         FILE_NAME\t= ;\nVERSION\t\t= 0;\nLINE_COUNT\t= {lines};\nMEMORY_SIZE\t= 0;\n\
         PROTECT\t\t= READ_WRITE;\nDEFAULT_GROUP\t= 1,*,*,*,*;\nCONTROL_CODE\t= 00000000 00000000;\n/MN\n"
    )
}

fn numbered(lines: &[String]) -> String {
    let mut s = String::new();
    for (i, l) in lines.iter().enumerate() {
        let _ = writeln!(s, "{:>4}:{l} ;", i + 1);
    }
    s
}

/// The program set: the main program first.
pub(crate) fn write(
    path: &ProgramPath,
    arm: &SixAxisArm,
    per_file: usize,
) -> Result<Vec<(String, String)>, Error> {
    let id = identifier(super::Format::Fanuc, &path.name);
    let chunks = parts(path, per_file);
    let n = chunks.len();
    let mut frames = Vec::new();
    for (label, f) in [("UT1", &path.tool), ("UF1", &path.work)] {
        let [r, p, w] = quaternion_zyx_deg(f.orientation);
        frames.push(format!(
            "  ! {label} X {} Y {} Z {}",
            fixed(f.position_mm[0], 3),
            fixed(f.position_mm[1], 3),
            fixed(f.position_mm[2], 3)
        ));
        frames.push(format!(
            "  ! {label} W {} P {} R {}",
            fixed(w, 3),
            fixed(p, 3),
            fixed(r, 3)
        ));
    }
    let mut files = Vec::new();
    let mut first = 0;
    let mut bodies = Vec::new();
    for (k, chunk) in chunks.iter().enumerate() {
        let name = part_name(&id, k, n);
        let (mut mn, pos) = part(path, arm, chunk, first);
        first += chunk.len();
        let mut lines = vec!["  UFRAME_NUM=1".to_string(), "  UTOOL_NUM=1".to_string()];
        if k == 0 {
            lines.splice(0..0, frames.iter().cloned());
        }
        lines.append(&mut mn);
        bodies.push((name, lines, pos));
    }
    if n == 1 {
        let (name, lines, pos) = bodies.pop().unwrap_or_default();
        let text = format!(
            "{}{}/POS\n{pos}/END\n",
            header(&name, "windcell path", lines.len()),
            numbered(&lines)
        );
        files.push((format!("{name}.ls"), text));
        return Ok(files);
    }
    let calls: Vec<String> = bodies
        .iter()
        .map(|(name, _, _)| format!("  CALL {name}"))
        .collect();
    files.push((
        format!("{id}.ls"),
        format!(
            "{}{}/POS\n/END\n",
            header(&id, "windcell path", calls.len()),
            numbered(&calls)
        ),
    ));
    for (name, lines, pos) in bodies {
        files.push((
            format!("{name}.ls"),
            format!(
                "{}{}/POS\n{pos}/END\n",
                header(&name, "windcell path part", lines.len()),
                numbered(&lines)
            ),
        ));
    }
    Ok(files)
}

fn part(
    path: &ProgramPath,
    arm: &SixAxisArm,
    targets: &[super::ProgramTarget],
    first: usize,
) -> (Vec<String>, String) {
    let mut mn = Vec::new();
    let mut pos = String::new();
    let sync = match path.mandrel {
        MandrelCoupling::Decoupled { sync } => Some(sync),
        MandrelCoupling::Coupled { .. } => None,
    };
    for (k, t) in targets.iter().enumerate() {
        let p = k + 1;
        let [r, pitch, w] = quaternion_zyx_deg(t.orientation);
        let cfg = fanuc_config(arm, &t.joints_deg);
        let ext = t
            .external_deg
            .map(|e| format!(",\n\tE1 = {} deg", fixed(e, 3)))
            .unwrap_or_default();
        let _ = write!(
            pos,
            "P[{p}]{{\n   GP1:\n\tUF : 1, UT : 1,\t\tCONFIG : '{}',\n\tX = {} mm,\tY = {} mm,\tZ = {} mm,\n\tW = {} deg,\tP = {} deg,\tR = {} deg{ext}\n}};\n",
            cfg.text(),
            fixed(t.position_mm[0], 3),
            fixed(t.position_mm[1], 3),
            fixed(t.position_mm[2], 3),
            fixed(w, 3),
            fixed(pitch, 3),
            fixed(r, 3)
        );
        if first + k == 0 {
            mn.push(format!("J P[{p}] 20% FINE"));
            continue;
        }
        let speed = (t.speed_mm_s.round() as i64).max(1);
        let stop = t.zone_mm <= 0.0 || (t.sync && sync.is_some());
        let term = if stop {
            "FINE".to_string()
        } else {
            format!("CNT{}", t.zone_mm.round().clamp(0.0, 100.0) as i64)
        };
        let mv = format!("L P[{p}] {speed}mm/sec {term}");
        match (t.sync, sync) {
            (true, Some(s)) => {
                mn.push(format!("  DO[{}]=ON", s.start_output));
                mn.push(mv);
                mn.push(format!("  WAIT DI[{}]=ON", s.in_position_input));
                mn.push(format!("  DO[{}]=OFF", s.start_output));
                mn.push(format!("  WAIT DI[{}]=OFF", s.in_position_input));
            }
            _ => mn.push(mv),
        }
    }
    (mn, pos)
}

// ---------------------------------------------------------------------------------------------
// Reading

#[derive(Debug, Clone, Copy)]
struct Position {
    position_mm: [f64; 3],
    orientation: [f64; 4],
    config: FanucConfig,
    e1: Option<f64>,
}

/// A move whose position is resolved once `/POS` is read.
struct PendingMove {
    item: usize,
    p: u32,
    at: (usize, usize),
}

/// Parses one `.ls` program.
pub(crate) fn parse(text: &str) -> Result<Unit, Error> {
    let lines: Vec<&str> = text.split('\n').collect();
    let mut i = 0;
    let blank = |l: &str| l.trim().is_empty();
    while i < lines.len() && blank(lines[i]) {
        i += 1;
    }
    let first = lines.get(i).copied().unwrap_or("");
    let Some(rest) = first.trim_start().strip_prefix("/PROG") else {
        return Err(Error::at(i + 1, 1, "expected /PROG"));
    };
    let toks = lex(rest, i + 1, None)?;
    let mut c = Cursor::new(&toks);
    let (name, _) = c.ident()?;
    // `Macro` or other attributes after the name are allowed.
    i += 1;
    let mut body = Vec::new();
    let mut pending = Vec::new();
    let mut section = "ATTR";
    let mut positions: HashMap<u32, Position> = HashMap::new();
    let mut ended = false;
    while i < lines.len() {
        let line = lines[i];
        let trimmed = line.trim();
        let line_no = i + 1;
        if ended {
            if !trimmed.is_empty() {
                return Err(Error::at(line_no, 1, "text after /END"));
            }
            i += 1;
            continue;
        }
        if let Some(s) = trimmed.strip_prefix('/') {
            let word: String = s.chars().take_while(char::is_ascii_alphabetic).collect();
            match word.as_str() {
                "ATTR" | "APPL" | "MN" => {
                    section = match word.as_str() {
                        "ATTR" => "ATTR",
                        "APPL" => "APPL",
                        _ => "MN",
                    };
                    i += 1;
                    continue;
                }
                "POS" => {
                    let end = lines[i + 1..]
                        .iter()
                        .position(|l| l.trim_start().starts_with("/END"))
                        .map(|k| i + 1 + k)
                        .ok_or_else(|| Error::at(line_no, 1, "/END is missing"))?;
                    let text = lines[i + 1..end].join("\n");
                    positions = parse_positions(&text, i + 2)?;
                    i = end;
                    continue;
                }
                "END" => {
                    ended = true;
                    i += 1;
                    continue;
                }
                _ => {
                    return Err(Error::at(line_no, 1, format!("unknown section /{word}")));
                }
            }
        }
        if section == "MN" && !trimmed.is_empty() {
            instruction(line, line_no, &mut body, &mut pending)?;
        }
        i += 1;
    }
    if !ended {
        return Err(Error::at(lines.len(), 1, "/END is missing"));
    }
    for m in pending {
        let p = positions.get(&m.p).ok_or_else(|| {
            Error::at(
                m.at.0,
                m.at.1,
                format!("P[{}] is not in the /POS section", m.p),
            )
        })?;
        if let Item::Step(Step::Move(t)) = &mut body[m.item] {
            t.position_mm = p.position_mm;
            t.orientation = p.orientation;
            t.config = ConfigData::Fanuc(p.config);
            t.external_deg = p.e1;
        }
    }
    Ok(Unit {
        routines: vec![Routine { name, body }],
        tool: None,
        work: None,
    })
}

fn on_off(c: &mut Cursor<'_>) -> Result<bool, Error> {
    let t = c.peek();
    if c.eat_ident("ON") {
        Ok(true)
    } else if c.eat_ident("OFF") {
        Ok(false)
    } else {
        Err(t.error(format!("expected ON or OFF, found {}", t.shown())))
    }
}

fn index(c: &mut Cursor<'_>) -> Result<u32, Error> {
    c.expect_punct("[")?;
    let n = c.integer()?;
    if c.eat_punct(":") {
        // A position or I/O comment: `P[3:"over the dome"]`.
        while !c.peek().is_punct("]") && c.peek().kind != Kind::Newline {
            c.next();
        }
    }
    c.expect_punct("]")?;
    Ok(n)
}

fn instruction(
    line: &str,
    line_no: usize,
    body: &mut Vec<Item>,
    pending: &mut Vec<PendingMove>,
) -> Result<(), Error> {
    let Some((toks, ccol)) = instruction_tokens(line, line_no)? else {
        return Ok(()); // a comment or a commented-out line
    };
    let mut c = Cursor::new(&toks);
    let t = c.peek();
    if c.eat_punct(";") {
        return c.newline();
    }
    let (word, _) = c.ident().map_err(|_| {
        Error::at(
            line_no,
            ccol,
            format!("expected an instruction, found {}", t.shown()),
        )
    })?;
    let too_large = |what: &str| Error::at(line_no, ccol, format!("{what} number too large"));
    match word.to_ascii_uppercase().as_str() {
        w @ ("J" | "L") => {
            let (p, target) = move_instruction(&mut c, w, line_no)?;
            pending.push(PendingMove {
                item: body.len(),
                p,
                at: (line_no, ccol),
            });
            body.push(Item::Step(Step::Move(target)));
        }
        "DO" => {
            let (n, on) = signal_state(&mut c)?;
            body.push(Item::Step(Step::Output {
                file: String::new(),
                line: line_no,
                number: u16::try_from(n).map_err(|_| too_large("output"))?,
                on,
            }));
        }
        "WAIT" => {
            let wt = c.peek();
            c.expect_ident_word("DI")
                .map_err(|_| wt.error("expected WAIT DI[n]=ON|OFF"))?;
            let (n, on) = signal_state(&mut c)?;
            body.push(Item::Step(Step::Wait {
                file: String::new(),
                line: line_no,
                number: u16::try_from(n).map_err(|_| too_large("input"))?,
                on,
            }));
        }
        "CALL" => {
            let (name, nt) = c.ident()?;
            c.expect_punct(";")?;
            c.newline()?;
            body.push(Item::Call {
                name,
                line: nt.line,
                column: nt.column,
            });
        }
        "UFRAME_NUM" | "UTOOL_NUM" => {
            c.expect_punct("=")?;
            c.integer()?;
            c.expect_punct(";")?;
            c.newline()?;
        }
        _ => {
            return Err(Error::at(
                line_no,
                ccol,
                format!("instruction {word} is not one a winding program uses"),
            ));
        }
    }
    Ok(())
}

/// The tokens of a `/MN` line `   12:  instruction ;` after its number and colon (columns those
/// of the line), with the column its instruction starts at; `None` for a comment (`!…`) or a
/// commented-out line (`//…`).
fn instruction_tokens(line: &str, line_no: usize) -> Result<Option<(Vec<Tok>, usize)>, Error> {
    let start = line.len() - line.trim_start().len();
    let digits = line[start..]
        .chars()
        .take_while(char::is_ascii_digit)
        .count();
    if digits == 0 {
        return Err(Error::at(
            line_no,
            start + 1,
            "expected the line number of a /MN line",
        ));
    }
    let after = start + digits;
    let Some(rest) = line[after..].strip_prefix(':') else {
        return Err(Error::at(
            line_no,
            after + 1,
            "expected `:` after the line number",
        ));
    };
    let col0 = after + 1;
    let content = rest.trim_start();
    let ccol = col0 + (rest.len() - content.len());
    if content.starts_with('!') || content.starts_with("//") {
        return Ok(None);
    }
    let toks = lex(rest, line_no, None)?
        .into_iter()
        .map(|mut t| {
            t.column += col0;
            t
        })
        .collect();
    Ok(Some((toks, ccol)))
}

/// `[n]=ON|OFF;` of a `DO` or `WAIT DI`: the signal's number and state.
fn signal_state(c: &mut Cursor<'_>) -> Result<(u32, bool), Error> {
    let n = index(c)?;
    c.expect_punct("=")?;
    let on = on_off(c)?;
    c.expect_punct(";")?;
    c.newline()?;
    Ok((n, on))
}

/// A move `J|L P[n] speed zone [options] ;` (`w` the motion letter) after its letter: the
/// position register it names and the target, its position resolved once `/POS` is read.
fn move_instruction(
    c: &mut Cursor<'_>,
    w: &str,
    line_no: usize,
) -> Result<(u32, ReadTarget), Error> {
    if !c.eat_ident("P") {
        let t = c.peek();
        return Err(t.error(format!("expected P[n], found {}", t.shown())));
    }
    let p = index(c)?;
    let (speed_mm_s, duration_s) = move_speed(c, w)?;
    let zone = move_zone(c)?;
    move_options(c)?;
    c.expect_punct(";")?;
    c.newline()?;
    Ok((
        p,
        ReadTarget {
            file: String::new(),
            line: line_no,
            motion: if w == "J" {
                Motion::Joint
            } else {
                Motion::Linear
            },
            position_mm: [0.0; 3],
            orientation: [1.0, 0.0, 0.0, 0.0],
            config: ConfigData::None,
            external_deg: None,
            speed_mm_s,
            duration_s,
            zone,
        },
    ))
}

/// A move's speed: `n%` (a joint move's, not reported), `n mm/sec` or `n sec` (its time), as
/// `(speed mm/s, duration s)`.
fn move_speed(c: &mut Cursor<'_>, w: &str) -> Result<(Option<f64>, Option<f64>), Error> {
    let st = c.peek();
    let v = c.number()?;
    let (speed_mm_s, duration_s) = if c.eat_punct("%") {
        if w == "L" {
            return Err(st.error("a linear move's speed is in mm/sec"));
        }
        (None, None)
    } else if c.eat_ident("mm") {
        c.expect_punct("/")?;
        c.expect_ident_word("sec")?;
        (Some(v), None)
    } else if c.eat_ident("sec") {
        (None, Some(v))
    } else {
        let t = c.peek();
        return Err(t.error(format!("expected %, mm/sec or sec, found {}", t.shown())));
    };
    if v <= 0.0 {
        return Err(st.error("the speed must be positive"));
    }
    Ok((speed_mm_s, duration_s))
}

/// A move's termination: `FINE` or `CNT0` … `CNT100`.
fn move_zone(c: &mut Cursor<'_>) -> Result<Zone, Error> {
    let zt = c.peek();
    let (z, _) = c.ident()?;
    let zu = z.to_ascii_uppercase();
    if zu == "FINE" {
        Ok(Zone::Fine)
    } else if let Some(n) = zu.strip_prefix("CNT") {
        match n.parse::<u8>() {
            Ok(k) if k <= 100 => Ok(Zone::Cnt(k)),
            _ => Err(zt.error("expected CNT0 … CNT100")),
        }
    } else {
        Err(zt.error(format!("expected FINE or CNTn, found `{z}`")))
    }
}

/// The motion options after a move's termination: those the reader knows change nothing it
/// reports (`ACCn`, `PTH`); any other is refused.
fn move_options(c: &mut Cursor<'_>) -> Result<(), Error> {
    while let Kind::Ident(o) = &c.peek().kind {
        let ou = o.to_ascii_uppercase();
        if ou.starts_with("ACC") || ou == "PTH" {
            c.next();
            if matches!(c.peek().kind, Kind::Number(_)) {
                c.next();
            }
        } else {
            let t = c.peek();
            return Err(t.error(format!(
                "motion option {o} is not one a winding program uses"
            )));
        }
    }
    Ok(())
}

fn config_text(s: &str, at: &Tok) -> Result<FanucConfig, Error> {
    let bad = || at.error(format!("CONFIG '{s}' is not 'F/N U/D T/B, t1, t4, t6'"));
    let mut parts = s.split(',');
    let letters: Vec<char> = parts
        .next()
        .ok_or_else(bad)?
        .chars()
        .filter(|c| !c.is_whitespace())
        .map(|c| c.to_ascii_uppercase())
        .collect();
    let [f, u, t] = letters.as_slice() else {
        return Err(bad());
    };
    let flip = match f {
        'F' => true,
        'N' => false,
        _ => return Err(bad()),
    };
    let up = match u {
        'U' => true,
        'D' => false,
        _ => return Err(bad()),
    };
    let front = match t {
        'T' => true,
        'B' => false,
        _ => return Err(bad()),
    };
    let mut turns = [0i32; 3];
    for turn in &mut turns {
        *turn = parts
            .next()
            .ok_or_else(bad)?
            .trim()
            .parse()
            .map_err(|_| bad())?;
        if turn.abs() > 8 {
            return Err(bad());
        }
    }
    if parts.next().is_some() {
        return Err(bad());
    }
    Ok(FanucConfig {
        flip,
        up,
        front,
        turns,
    })
}

fn parse_positions(text: &str, first_line: usize) -> Result<HashMap<u32, Position>, Error> {
    let toks = lex(text, first_line, None)?;
    let mut c = Cursor::new(&toks);
    let mut out = HashMap::new();
    loop {
        c.skip_newlines();
        if c.at_end() {
            return Ok(out);
        }
        let pt = c.peek();
        c.expect_ident_word("P")?;
        let n = index(&mut c)?;
        c.skip_newlines();
        c.expect_punct("{")?;
        c.skip_newlines();
        let mut pos: Option<Position> = None;
        while !c.peek().is_punct("}") {
            let (group, gt) = c.ident()?;
            c.expect_punct(":")?;
            c.skip_newlines();
            let g = group.to_ascii_uppercase();
            if g == "GP1" {
                pos = Some(group1(&mut c)?);
            } else if g.starts_with("GP") {
                // Another motion group: its J1 is read as the external axis.
                let mut j1 = None;
                while !c.at_end()
                    && !c.peek().is_punct("}")
                    && !matches!(&c.peek().kind, Kind::Ident(s) if s.to_ascii_uppercase().starts_with("GP"))
                {
                    if c.peek().is_ident("J1") && c.peek_at(1).is_punct("=") {
                        c.pos += 2;
                        j1 = Some(c.number()?);
                    } else {
                        c.next();
                    }
                }
                if let (Some(p), Some(e)) = (pos.as_mut(), j1) {
                    p.e1 = Some(e);
                }
            } else {
                return Err(gt.error(format!("expected GP1 or GPn, found `{group}`")));
            }
            c.skip_newlines();
            if c.at_end() {
                return Err(pt.error("P[n]{ is not closed"));
            }
        }
        c.expect_punct("}")?;
        c.expect_punct(";")?;
        let p = pos.ok_or_else(|| pt.error(format!("P[{n}] has no GP1 group")))?;
        if out.insert(n, p).is_some() {
            return Err(pt.error(format!("P[{n}] is given twice")));
        }
    }
}

fn group1(c: &mut Cursor<'_>) -> Result<Position, Error> {
    let mut config = None;
    let mut v: [Option<f64>; 7] = [None; 7];
    loop {
        c.skip_newlines();
        let (key, kt) = c.ident()?;
        let k = key.to_ascii_uppercase();
        match k.as_str() {
            "UF" | "UT" => {
                c.expect_punct(":")?;
                c.integer()?;
            }
            "CONFIG" => {
                c.expect_punct(":")?;
                let st = c.next();
                let Kind::Str(s) = &st.kind else {
                    return Err(st.error("expected the CONFIG string"));
                };
                config = Some(config_text(s, st)?);
            }
            "X" | "Y" | "Z" | "W" | "P" | "R" | "E1" => {
                c.expect_punct("=")?;
                let x = c.number()?;
                let unit = c.peek();
                let want = if matches!(k.as_str(), "X" | "Y" | "Z") {
                    "mm"
                } else {
                    "deg"
                };
                if !(c.eat_ident(want) || (k == "E1" && c.eat_ident("mm"))) {
                    return Err(unit.error(format!("expected {want} after {k}")));
                }
                let i = ["X", "Y", "Z", "W", "P", "R", "E1"]
                    .iter()
                    .position(|n| *n == k)
                    .unwrap_or(0);
                if v[i].replace(x).is_some() {
                    return Err(kt.error(format!("{k} is given twice")));
                }
            }
            "J1" | "J2" | "J3" | "J4" | "J5" | "J6" => {
                return Err(
                    kt.error("a joint position is not read (windcell writes Cartesian positions)")
                );
            }
            _ => return Err(kt.error(format!("unknown position field {key}"))),
        }
        c.skip_newlines();
        if !c.eat_punct(",") {
            break;
        }
    }
    let at = c.peek();
    let mut xyzwpr = [0.0; 6];
    for (i, x) in xyzwpr.iter_mut().enumerate() {
        *x = v[i].ok_or_else(|| at.error("the position lacks one of X, Y, Z, W, P, R"))?;
    }
    let config = config.ok_or_else(|| at.error("the position has no CONFIG"))?;
    Ok(Position {
        position_mm: [xyzwpr[0], xyzwpr[1], xyzwpr[2]],
        orientation: zyx_deg_quaternion([xyzwpr[5], xyzwpr[4], xyzwpr[3]]),
        config,
        e1: v[6],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_strings_in_their_written_forms() {
        let t = lex("'x'", 1, None).unwrap();
        let c = config_text("N U T, 0, 1, -1", &t[0]).unwrap();
        assert_eq!(
            (c.flip, c.up, c.front, c.turns),
            (false, true, true, [0, 1, -1])
        );
        let c = config_text("FDB,0,0,0", &t[0]).unwrap();
        assert_eq!((c.flip, c.up, c.front), (true, false, false));
        for bad in [
            "N U",
            "N U T, 0, 0",
            "X U T, 0, 0, 0",
            "N U T, 0, 0, 0, 0",
            "N U T, a, 0, 0",
        ] {
            assert!(config_text(bad, &t[0]).is_err(), "{bad}");
        }
    }
}
