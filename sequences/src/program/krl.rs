//! KUKA KRL programs (`.src` + `.dat`), after the KUKA System Software 8 "Operating and
//! Programming Instructions for System Integrators" (module structure `DEF … END` with its
//! `DEFDAT … ENDDAT` data list, `E6POS`, `FRAME`, `$VEL.CP`, `$APO.CDIS`, `C_DIS`, `$BASE`,
//! `$TOOL`, `EK`, `$OUT`, `WAIT FOR $IN`, Status and Turn).
//!
//! # What is written
//! - Each target `DECL E6POS XPn={X …,Y …,Z …,A …,B …,C …,S s,T t,E1 …,…,E6 …}` in the module's
//!   `.dat`: mm with 3 decimals, `A`, `B`, `C` the Z-Y′-X″ Euler angles in degrees with 4
//!   decimals (`R = Rz(A)·Ry(B)·Rx(C)`), `S`/`T` from the joints ([`super::config::kuka_status`]),
//!   coupled: `E1` the mandrel angle in degrees, `E2`–`E6` 0; decoupled: no external axis
//!   values (KRL's partial aggregate: the axes keep their values).
//! - The `.src`: `BAS(#INITMOV,0)` (KUKA's standard initialisation of the velocities and
//!   accelerations), `$TOOL` and `$BASE` as `FRAME`s; decoupled `$BASE` the work frame, coupled
//!   `$BASE=EK(MACHINE_DEF[n+1].ROOT,MACHINE_DEF[n+1].MECH_TYPE,{work frame})`: the base rides on
//!   external kinematic `n` (the mandrel frame given relative to the positioner's flange frame,
//!   KUKA's "external kinematic system" base). The first target `PTP XP1` (a PTP motion honours
//!   `S` and `T`), every other `LIN XPn` with `C_DIS` when the zone is non-zero, `$VEL.CP` (m/s,
//!   4 decimals) and `$APO.CDIS` (mm) set when they change.
//! - Sync at a target (decoupled): `$OUT[n]=TRUE` before the move, the move to an exact stop,
//!   `WAIT FOR $IN[m]`, `$OUT[n]=FALSE`, `WAIT FOR NOT $IN[m]`.
//! - Split: at most [`TARGETS_PER_FILE`] targets per module (at most 7 lines each, so a `.src` of
//!   at most about 1400 lines); the main `.src` calls the parts in order.

use std::collections::HashMap;
use std::fmt::Write as _;

use paths::arm::SixAxisArm;

use super::config::{KukaStatus, kuka_status};
use super::lex::{Cursor, Kind, Tok, lex};
use super::{
    ConfigData, Frame, Item, MandrelCoupling, Motion, ProgramPath, ReadTarget, Routine, Step, Unit,
    Zone, fixed, identifier, part_name, parts, quaternion_zyx_deg, zyx_deg_quaternion,
};
use crate::Error;

/// Targets per module before the program is split.
pub const TARGETS_PER_FILE: usize = 200;

const HEADER: &str = "&ACCESS RVP\n&REL 1\n";

fn frame_text(f: &Frame) -> String {
    let [a, b, c] = quaternion_zyx_deg(f.orientation);
    format!(
        "{{X {},Y {},Z {},A {},B {},C {}}}",
        fixed(f.position_mm[0], 3),
        fixed(f.position_mm[1], 3),
        fixed(f.position_mm[2], 3),
        fixed(a, 4),
        fixed(b, 4),
        fixed(c, 4)
    )
}

/// The program set: the main `.src` first (with its `.dat` when not split).
pub(crate) fn write(
    path: &ProgramPath,
    arm: &SixAxisArm,
    per_file: usize,
) -> Result<Vec<(String, String)>, Error> {
    let id = identifier(super::Format::Krl, &path.name);
    let chunks = parts(path, per_file);
    let n = chunks.len();
    let mut head = String::new();
    let _ = writeln!(head, "  BAS(#INITMOV,0)");
    let _ = writeln!(head, "  $TOOL={}", frame_text(&path.tool));
    match &path.mandrel {
        MandrelCoupling::Decoupled { .. } => {
            let _ = writeln!(head, "  $BASE={}", frame_text(&path.work));
        }
        MandrelCoupling::Coupled { axis } => {
            let m = u32::from(axis.number) + 1;
            let _ = writeln!(
                head,
                "  $BASE=EK(MACHINE_DEF[{m}].ROOT,MACHINE_DEF[{m}].MECH_TYPE,{})",
                frame_text(&path.work)
            );
        }
    }
    let comment = format!(
        "  ;windcell path {}: {} targets",
        path.name.replace(['\n', '\r'], " "),
        path.targets.len()
    );
    let mut files = Vec::new();
    let mut first = 0;
    let mut bodies = Vec::new();
    for (k, chunk) in chunks.iter().enumerate() {
        let name = part_name(&id, k, n);
        bodies.push((name, part(path, arm, chunk, first)));
        first += chunk.len();
    }
    if n == 1 {
        let (_, (src, dat)) = bodies.pop().unwrap_or_default();
        files.push((
            format!("{id}.src"),
            format!("{HEADER}DEF {id}()\n{comment}\n{head}{src}END\n"),
        ));
        files.push((
            format!("{id}.dat"),
            format!("{HEADER}DEFDAT {id}\n{dat}ENDDAT\n"),
        ));
        return Ok(files);
    }
    let mut main = format!("{HEADER}DEF {id}()\n{comment}, {n} modules run in turn\n{head}");
    for (name, _) in &bodies {
        let _ = writeln!(main, "  {name}()");
    }
    main.push_str("END\n");
    files.push((format!("{id}.src"), main));
    for (name, (src, dat)) in bodies {
        files.push((
            format!("{name}.src"),
            format!("{HEADER}DEF {name}()\n{src}END\n"),
        ));
        files.push((
            format!("{name}.dat"),
            format!("{HEADER}DEFDAT {name}\n{dat}ENDDAT\n"),
        ));
    }
    Ok(files)
}

fn part(
    path: &ProgramPath,
    arm: &SixAxisArm,
    targets: &[super::ProgramTarget],
    first: usize,
) -> (String, String) {
    let mut src = String::new();
    let mut dat = String::new();
    let sync = match path.mandrel {
        MandrelCoupling::Decoupled { sync } => Some(sync),
        MandrelCoupling::Coupled { .. } => None,
    };
    let mut vel: Option<String> = None;
    let mut apo: Option<String> = None;
    for (k, t) in targets.iter().enumerate() {
        let index = first + k + 1;
        let [a, b, c] = quaternion_zyx_deg(t.orientation);
        let KukaStatus { s, t: turn } = kuka_status(arm, &t.joints_deg);
        let ext = t.external_deg.map_or(String::new(), |e| {
            format!(",E1 {},E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0", fixed(e, 4))
        });
        let _ = writeln!(
            dat,
            "DECL E6POS XP{index}={{X {},Y {},Z {},A {},B {},C {},S {s},T {turn}{ext}}}",
            fixed(t.position_mm[0], 3),
            fixed(t.position_mm[1], 3),
            fixed(t.position_mm[2], 3),
            fixed(a, 4),
            fixed(b, 4),
            fixed(c, 4)
        );
        if first + k == 0 {
            let _ = writeln!(src, "  PTP XP{index}");
            continue;
        }
        let v = fixed(t.speed_mm_s / 1000.0, 4);
        if vel.as_deref() != Some(v.as_str()) {
            let _ = writeln!(src, "  $VEL.CP={v}");
            vel = Some(v);
        }
        let stop = t.zone_mm <= 0.0 || (t.sync && sync.is_some());
        let approx = if stop {
            ""
        } else {
            let z = fixed(t.zone_mm, 2);
            if apo.as_deref() != Some(z.as_str()) {
                let _ = writeln!(src, "  $APO.CDIS={z}");
                apo = Some(z);
            }
            " C_DIS"
        };
        match (t.sync, sync) {
            (true, Some(s)) => {
                let _ = writeln!(src, "  $OUT[{}]=TRUE", s.start_output);
                let _ = writeln!(src, "  LIN XP{index}{approx}");
                let _ = writeln!(src, "  WAIT FOR $IN[{}]", s.in_position_input);
                let _ = writeln!(src, "  $OUT[{}]=FALSE", s.start_output);
                let _ = writeln!(src, "  WAIT FOR NOT $IN[{}]", s.in_position_input);
            }
            _ => {
                let _ = writeln!(src, "  LIN XP{index}{approx}");
            }
        }
    }
    (src, dat)
}

// ---------------------------------------------------------------------------------------------
// Reading

/// A point of a data list.
#[derive(Debug, Clone, Copy)]
struct Point {
    frame: Frame,
    status: Option<KukaStatus>,
    e1: Option<f64>,
}

/// The file stem (module name) of a file name, upper case.
fn stem(name: &str) -> String {
    let base = name.rsplit(['/', '\\']).next().unwrap_or(name);
    base.rsplit_once('.')
        .map_or(base, |(s, _)| s)
        .to_ascii_uppercase()
}

/// Parses a whole set: each `.dat` for its points, then each `.src` with the points of the
/// `.dat` of the same name.
pub(crate) fn parse_set(files: &[(String, String)]) -> Result<Vec<(String, Unit)>, Error> {
    let mut data: HashMap<String, HashMap<String, Point>> = HashMap::new();
    let is_dat = |n: &str| n.to_ascii_lowercase().ends_with(".dat");
    for (name, text) in files.iter().filter(|(n, _)| is_dat(n)) {
        let points = parse_dat(text).map_err(|e| e.in_file(name))?;
        data.insert(stem(name), points);
    }
    let empty = HashMap::new();
    let mut out = Vec::new();
    for (name, text) in files {
        if is_dat(name) {
            out.push((name.clone(), Unit::default()));
            continue;
        }
        let points = data.get(&stem(name)).unwrap_or(&empty);
        let unit = parse_src(text, points).map_err(|e| e.in_file(name))?;
        out.push((name.clone(), unit));
    }
    Ok(out)
}

/// The lines of a text as token slices (without their line ends), skipping blank lines,
/// comments and the `&` header lines.
fn lines(toks: &[Tok]) -> Vec<&[Tok]> {
    let mut out = Vec::new();
    let mut start = 0;
    for (i, t) in toks.iter().enumerate() {
        if t.kind == Kind::Newline {
            let line = &toks[start..i];
            start = i + 1;
            if line.is_empty() || line[0].is_punct("&") {
                continue;
            }
            out.push(line);
        }
    }
    out
}

fn line_cursor(line: &[Tok]) -> (Vec<Tok>, usize) {
    let mut v = line.to_vec();
    let last = line.last().map_or((1, 1), |t| (t.line, t.column + 1));
    v.push(Tok {
        kind: Kind::Newline,
        line: last.0,
        column: last.1,
    });
    (v, 0)
}

fn parse_dat(text: &str) -> Result<HashMap<String, Point>, Error> {
    let toks = lex(text, 1, Some(';'))?;
    let ls = lines(&toks);
    let mut points = HashMap::new();
    let Some(first) = ls.first() else {
        return Err(Error::at(1, 1, "the data list is empty (expected DEFDAT)"));
    };
    if !first[0].is_ident("DEFDAT") {
        return Err(first[0].error(format!("expected DEFDAT, found {}", first[0].shown())));
    }
    let mut ended = false;
    for line in &ls[1..] {
        if ended {
            return Err(line[0].error(format!("{} after ENDDAT", line[0].shown())));
        }
        let (v, _) = line_cursor(line);
        let mut c = Cursor::new(&v);
        if c.eat_ident("ENDDAT") {
            c.newline()?;
            ended = true;
            continue;
        }
        c.eat_ident("DECL");
        c.eat_ident("GLOBAL");
        let (kind, _) = c.ident()?;
        if !matches!(kind.to_ascii_uppercase().as_str(), "E6POS" | "POS") {
            // Other data (FDAT, LDAT, INT, EXT declarations the editor adds): not the reader's.
            continue;
        }
        let (name, _) = c.ident()?;
        c.expect_punct("=")?;
        let p = point(&mut c)?;
        c.newline()?;
        points.insert(name.to_ascii_uppercase(), p);
    }
    if !ended {
        return Err(Error::at(
            text.lines().count().max(1),
            1,
            "ENDDAT is missing",
        ));
    }
    Ok(points)
}

/// A structure literal `{NAME value, …}` of numbers (and `'B…'` bit strings) as name → value.
fn structure(c: &mut Cursor<'_>) -> Result<Vec<(String, f64)>, Error> {
    let open = c.peek();
    c.expect_punct("{")?;
    // An optional type name (`{E6POS: X 1, …}`).
    if matches!(c.peek().kind, Kind::Ident(_)) && c.peek_at(1).is_punct(":") {
        c.pos += 2;
    }
    let mut fields = Vec::new();
    loop {
        let (name, nt) = c.ident()?;
        let v = match &c.peek().kind {
            Kind::Str(s) => {
                let t = c.next();
                let bits = s
                    .strip_prefix('B')
                    .or_else(|| s.strip_prefix('b'))
                    .ok_or_else(|| t.error("expected a bit string 'B…'"))?;
                let v = u32::from_str_radix(bits, 2)
                    .map_err(|_| t.error("expected a bit string 'B…'"))?;
                f64::from(v)
            }
            _ => c.number()?,
        };
        if fields
            .iter()
            .any(|(n, _): &(String, f64)| n.eq_ignore_ascii_case(&name))
        {
            return Err(nt.error(format!("{name} is given twice")));
        }
        fields.push((name.to_ascii_uppercase(), v));
        if fields.len() > 64 {
            return Err(open.error("too many components"));
        }
        if c.eat_punct(",") {
            continue;
        }
        c.expect_punct("}")?;
        return Ok(fields);
    }
}

fn point(c: &mut Cursor<'_>) -> Result<Point, Error> {
    let at = c.peek();
    let fields = structure(c)?;
    let get = |n: &str| fields.iter().find(|(k, _)| k == n).map(|(_, v)| *v);
    let mut xyzabc = [0.0; 6];
    for (i, n) in ["X", "Y", "Z", "A", "B", "C"].iter().enumerate() {
        xyzabc[i] = get(n).ok_or_else(|| at.error(format!("the point has no {n}")))?;
    }
    let status = match (get("S"), get("T")) {
        (Some(s), Some(t)) => {
            if !(s.fract() == 0.0
                && (0.0..=255.0).contains(&s)
                && t.fract() == 0.0
                && (0.0..=255.0).contains(&t))
            {
                return Err(at.error("S and T must be whole numbers 0–255"));
            }
            Some(KukaStatus {
                s: s as u8,
                t: t as u8,
            })
        }
        _ => None,
    };
    for (k, _) in &fields {
        if !matches!(
            k.as_str(),
            "X" | "Y" | "Z" | "A" | "B" | "C" | "S" | "T" | "E1" | "E2" | "E3" | "E4" | "E5" | "E6"
        ) {
            return Err(at.error(format!("a point has no component {k}")));
        }
    }
    Ok(Point {
        frame: Frame {
            position_mm: [xyzabc[0], xyzabc[1], xyzabc[2]],
            orientation: zyx_deg_quaternion([xyzabc[3], xyzabc[4], xyzabc[5]]),
        },
        status,
        e1: get("E1"),
    })
}

/// `$NAME` optionally followed by `.FIELD` or `[n]`: the upper-case name with the field, and the
/// index.
fn system_variable(c: &mut Cursor<'_>) -> Result<(String, Option<u32>), Error> {
    let (mut name, _) = c.ident()?;
    name.make_ascii_uppercase();
    let mut index = None;
    if c.eat_punct("[") {
        index = Some(c.integer()?);
        c.expect_punct("]")?;
    }
    if c.eat_punct(".") {
        let (f, _) = c.ident()?;
        name = format!("{name}.{}", f.to_ascii_uppercase());
    }
    Ok((name, index))
}

fn boolean(c: &mut Cursor<'_>) -> Result<bool, Error> {
    let t = c.peek();
    if c.eat_ident("TRUE") {
        Ok(true)
    } else if c.eat_ident("FALSE") {
        Ok(false)
    } else {
        Err(t.error(format!("expected TRUE or FALSE, found {}", t.shown())))
    }
}

/// The motion settings a routine's moves take from the assignments before them.
#[derive(Debug, Clone, Copy, Default)]
struct Settings {
    /// `$VEL.CP`, mm/s.
    vel_mm_s: Option<f64>,
    /// `$APO.CDIS`, mm.
    cdis_mm: Option<f64>,
}

fn parse_src(text: &str, points: &HashMap<String, Point>) -> Result<Unit, Error> {
    let toks = lex(text, 1, Some(';'))?;
    let ls = lines(&toks);
    let mut unit = Unit::default();
    let mut current: Option<Routine> = None;
    let mut settings = Settings::default();
    for line in ls {
        let (v, _) = line_cursor(line);
        let mut c = Cursor::new(&v);
        let t = c.peek();
        let Some(routine) = current.as_mut() else {
            current = Some(definition(&mut c)?);
            settings = Settings::default();
            continue;
        };
        if c.eat_ident("END") {
            c.newline()?;
            if let Some(r) = current.take() {
                unit.routines.push(r);
            }
            continue;
        }
        if let Some(item) = statement(&mut c, t, points, &mut settings, &mut unit)? {
            routine.body.push(item);
        }
    }
    if current.is_some() {
        return Err(Error::at(text.lines().count().max(1), 1, "END is missing"));
    }
    Ok(unit)
}

/// `[GLOBAL] DEF name()`: the routine it opens.
fn definition(c: &mut Cursor<'_>) -> Result<Routine, Error> {
    let t = c.peek();
    c.eat_ident("GLOBAL");
    if !c.eat_ident("DEF") {
        return Err(t.error(format!("expected DEF, found {}", t.shown())));
    }
    let (name, _) = c.ident()?;
    c.expect_punct("(")?;
    c.expect_punct(")")?;
    c.newline()?;
    Ok(Routine {
        name,
        body: Vec::new(),
    })
}

/// One statement of a routine body, its first token `t`: the item it adds to the body, if any
/// (assignments set `settings` or the unit's frames).
fn statement(
    c: &mut Cursor<'_>,
    t: &Tok,
    points: &HashMap<String, Point>,
    settings: &mut Settings,
    unit: &mut Unit,
) -> Result<Option<Item>, Error> {
    match &t.kind {
        Kind::Ident(w) if w.starts_with('$') => assignment(c, t, settings, unit),
        Kind::Ident(w) if w.eq_ignore_ascii_case("WAIT") => wait_statement(c, t),
        Kind::Ident(w) if w.eq_ignore_ascii_case("LIN") || w.eq_ignore_ascii_case("PTP") => {
            let joint = w.eq_ignore_ascii_case("PTP");
            move_statement(c, t, joint, points, settings).map(Some)
        }
        Kind::Ident(w) if w.eq_ignore_ascii_case("BAS") => {
            // KUKA's initialisation (BAS.SRC): velocities and accelerations, no motion.
            while c.peek().kind != Kind::Newline {
                c.next();
            }
            Ok(None)
        }
        Kind::Ident(w) if w.eq_ignore_ascii_case("HALT") => {
            c.next();
            c.newline()?;
            Ok(None)
        }
        Kind::Ident(_) => {
            let (name, _) = c.ident()?;
            c.expect_punct("(")?;
            c.expect_punct(")")?;
            c.newline()?;
            Ok(Some(Item::Call {
                name,
                line: t.line,
                column: t.column,
            }))
        }
        _ => Err(t.error(format!("expected a statement, found {}", t.shown()))),
    }
}

/// An assignment to a system variable (`$VEL.CP = …`, `$OUT[n] = TRUE`, `$TOOL = {…}`, …), at
/// `t`: an output is an item; the others set `settings` or the unit's frames, or are passed over.
fn assignment(
    c: &mut Cursor<'_>,
    t: &Tok,
    settings: &mut Settings,
    unit: &mut Unit,
) -> Result<Option<Item>, Error> {
    let (var, index) = system_variable(c)?;
    c.expect_punct("=")?;
    let mut item = None;
    match (var.as_str(), index) {
        ("$VEL.CP", None) => {
            let v = c.number()?;
            if v <= 0.0 {
                return Err(t.error("$VEL.CP must be positive"));
            }
            settings.vel_mm_s = Some(v * 1000.0);
        }
        ("$APO.CDIS", None) => {
            let v = c.number()?;
            if v < 0.0 {
                return Err(t.error("$APO.CDIS must not be negative"));
            }
            settings.cdis_mm = Some(v);
        }
        ("$OUT", Some(n)) => {
            let on = boolean(c)?;
            let number = u16::try_from(n).map_err(|_| t.error("output number too large"))?;
            item = Some(Item::Step(Step::Output {
                file: String::new(),
                line: t.line,
                number,
                on,
            }));
        }
        ("$TOOL", None) => {
            let p = frame(c)?;
            unit.tool.get_or_insert(p);
        }
        ("$BASE", None) => {
            let p = base_frame(c)?;
            unit.work.get_or_insert(p);
        }
        ("$VEL_AXIS" | "$ACC_AXIS", Some(_))
        | (
            "$ACC.CP" | "$ADVANCE" | "$VEL.ORI1" | "$VEL.ORI2" | "$ACC.ORI1" | "$ACC.ORI2"
            | "$ORI_TYPE",
            None,
        ) => {
            while c.peek().kind != Kind::Newline {
                c.next();
            }
        }
        _ => {
            return Err(t.error(format!(
                "assignment to {var} is not one a winding program uses"
            )));
        }
    }
    c.newline()?;
    Ok(item)
}

/// The value of `$BASE`: a frame, or `EK(…, {offset}, …)` whose offset frame is the work frame.
fn base_frame(c: &mut Cursor<'_>) -> Result<Frame, Error> {
    if !c.eat_ident("EK") {
        return frame(c);
    }
    c.expect_punct("(")?;
    let mut depth = 0;
    while !(c.peek().is_punct("{") && depth == 0) {
        if c.peek().kind == Kind::Newline {
            return Err(c.peek().error("expected the EK offset frame"));
        }
        if c.peek().is_punct("(") {
            depth += 1;
        }
        if c.peek().is_punct(")") {
            depth -= 1;
        }
        c.next();
    }
    let f = frame(c)?;
    c.expect_punct(")")?;
    Ok(f)
}

/// `WAIT SEC t` (passed over) or `WAIT FOR [NOT] $IN[n] [== TRUE|FALSE]`, at `t`.
fn wait_statement(c: &mut Cursor<'_>, t: &Tok) -> Result<Option<Item>, Error> {
    c.next();
    if c.eat_ident("SEC") {
        c.number()?;
        c.newline()?;
        return Ok(None);
    }
    c.expect_ident_word("FOR")?;
    let mut on = !c.eat_ident("NOT");
    let (var, index) = system_variable(c)?;
    let (true, Some(n)) = (var == "$IN", index) else {
        return Err(t.error("expected WAIT FOR $IN[n]"));
    };
    if c.eat_punct("==") {
        on = on == boolean(c)?;
    }
    c.newline()?;
    Ok(Some(Item::Step(Step::Wait {
        file: String::new(),
        line: t.line,
        number: u16::try_from(n).map_err(|_| t.error("input number too large"))?,
        on,
    })))
}

/// `LIN` or `PTP` (`joint`), at `t`, to an inline point or one of the module's `.dat`
/// (`points`), with its approximation (`C_DIS`, `C_PTP`) from `settings`.
fn move_statement(
    c: &mut Cursor<'_>,
    t: &Tok,
    joint: bool,
    points: &HashMap<String, Point>,
    settings: &Settings,
) -> Result<Item, Error> {
    c.next();
    let p = match &c.peek().kind {
        Kind::Punct("{") => point(c)?,
        _ => {
            let (name, nt) = c.ident()?;
            *points.get(&name.to_ascii_uppercase()).ok_or_else(|| {
                nt.error(format!("point {name} is not declared in the module's .dat"))
            })?
        }
    };
    let zone = if c.eat_ident("C_DIS") {
        Zone::Distance(
            settings
                .cdis_mm
                .ok_or_else(|| t.error("C_DIS before $APO.CDIS is set"))?,
        )
    } else if c.eat_ident("C_PTP") {
        Zone::Distance(settings.cdis_mm.unwrap_or(0.0))
    } else {
        Zone::Fine
    };
    c.newline()?;
    Ok(Item::Step(Step::Move(ReadTarget {
        file: String::new(),
        line: t.line,
        motion: if joint { Motion::Joint } else { Motion::Linear },
        position_mm: p.frame.position_mm,
        orientation: p.frame.orientation,
        config: p.status.map_or(ConfigData::None, ConfigData::Kuka),
        external_deg: p.e1,
        speed_mm_s: if joint { None } else { settings.vel_mm_s },
        duration_s: None,
        zone,
    })))
}

fn frame(c: &mut Cursor<'_>) -> Result<Frame, Error> {
    let at = c.peek();
    let fields = structure(c)?;
    let mut v = [0.0; 6];
    for (k, x) in fields {
        let i = ["X", "Y", "Z", "A", "B", "C"]
            .iter()
            .position(|n| *n == k)
            .ok_or_else(|| at.error(format!("a frame has no component {k}")))?;
        v[i] = x;
    }
    Ok(Frame {
        position_mm: [v[0], v[1], v[2]],
        orientation: zyx_deg_quaternion([v[3], v[4], v[5]]),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A module as KUKA's editor saves it: bit-string Status and Turn, an inline aggregate,
    /// folds, `&` headers and other declarations.
    #[test]
    fn editor_forms_are_read() {
        let dat = "&ACCESS RVP\n&REL 3\nDEFDAT  SEAM PUBLIC\n;FOLD EXTERNAL DECLARATIONS\n\
                   EXT BAS (BAS_COMMAND :IN,REAL :IN )\n;ENDFOLD\n\
                   DECL E6POS XP1={X 10.0,Y -2.5,Z 300,A 90,B 0,C 180,S 'B110',T 'B000010',E1 0.0}\n\
                   DECL FDAT FP1={TOOL_NO 1,BASE_NO 0,IPO_FRAME #BASE}\nENDDAT\n";
        let src = "&ACCESS RVP\n&REL 3\nDEF SEAM( )\n;FOLD INI\n  BAS (#INITMOV,0 )\n;ENDFOLD (INI)\n\
                   $vel.cp = 0.2\n$APO.CDIS = 1.5\nPTP XP1\nlin {X 20,Y 0,Z 300,A 0,B 0,C 0} C_DIS\n\
                   WAIT FOR $IN[3]==FALSE\nEND\n";
        let units = parse_set(&[
            ("SEAM.dat".to_string(), dat.to_string()),
            ("SEAM.src".to_string(), src.to_string()),
        ])
        .unwrap();
        let body = &units[1].1.routines[0].body;
        let Item::Step(Step::Move(first)) = &body[0] else {
            panic!("{body:?}");
        };
        assert_eq!(first.config, ConfigData::Kuka(KukaStatus { s: 6, t: 2 }));
        assert_eq!(first.motion, Motion::Joint);
        assert_eq!(first.external_deg, Some(0.0));
        let Item::Step(Step::Move(second)) = &body[1] else {
            panic!("{body:?}");
        };
        assert_eq!(second.zone, Zone::Distance(1.5));
        assert_eq!(second.speed_mm_s, Some(200.0));
        assert_eq!(second.config, ConfigData::None);
        assert!(matches!(
            body[2],
            Item::Step(Step::Wait {
                number: 3,
                on: false,
                ..
            })
        ));
    }
}
