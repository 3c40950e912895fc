//! ABB RAPID modules (`.mod`), after the RAPID Instructions, Functions and Data types technical
//! reference manual (data types `robtarget`, `confdata`, `speeddata`, `zonedata`, `tooldata`,
//! `wobjdata`; instructions `MoveL`, `MoveJ`, `SetDO`, `WaitDI`, `Load`, `UnLoad`; late binding
//! `%"name"%`).
//!
//! # What is written
//! - Each target a `CONST robtarget pN := [[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax_a,…]]`:
//!   mm with 3 decimals, the quaternion with 6 decimals, `q1` the real part, sign normalised so
//!   that `q1 ≥ 0`; `confdata` from the joints ([`super::config::abb_conf`]); `eax_a` the
//!   mandrel angle in degrees when coupled, every unused external axis `9E+09`.
//! - One `speeddata vWn := [v_tcp, 500, 5000, 1000]` per distinct speed (0.1 mm/s) and the move's
//!   time as the `\T` argument: `\T` makes the controller take exactly the plan's segment time
//!   (the reference manual: "\T … the total time in seconds during which the robot moves"),
//!   which one speed per segment reproduces only up to its rounding; `v_tcp` stays the nominal
//!   speed an operator reads.
//! - One `zonedata zWn := [FALSE, z, 1.5z, 1.5z, 0.15z, 1.5z, 0.15z]` per distinct zone (the
//!   proportions of the predefined `z10` … `z200`), `fine` for a stop point.
//! - `PERS tooldata tWEye` (the eye, `robhold TRUE`, a nominal 1 kg load) and `PERS wobjdata
//!   wWWork`: decoupled `[FALSE, TRUE, "", [uframe], [oframe 0]]`; coupled a coordinated work
//!   object `[FALSE, FALSE, "STN1", …]` (`ufprog FALSE`, `ufmec` the positioner's mechanical
//!   unit) whose user frame is the mandrel frame.
//! - The first target a `MoveJ … v100, fine` (it honours `confdata`), every other a `MoveL`.
//! - Sync at a target (decoupled): `SetDO doWcN, 1;` before the move, the move to a stop point,
//!   `WaitDI diWcM, 1; SetDO doWcN, 0; WaitDI diWcM, 0;` after it; the signals `doWcN`/`diWcM`
//!   are the robot's digital output N and input M, named so in the I/O configuration.
//! - Split: at most [`TARGETS_PER_MODULE`] targets per module; the part `NAME_Pk.mod` holds
//!   module `MNAME_Pk` with procedure `NAME_Pk` (a module and a routine may not share a name);
//!   the main module loads each part (`Load \Dynamic, "HOME:/…"`), runs its procedure by late
//!   binding and unloads it.

use std::collections::HashMap;
use std::fmt::Write as _;

use paths::arm::SixAxisArm;

use super::config::{AbbConf, abb_conf};
use super::lex::{Cursor, Kind, Tok, lex};
use super::{
    ConfigData, Frame, Item, MandrelCoupling, Motion, ProgramPath, ReadTarget, Routine, Step, Unit,
    Zone, fixed, identifier, part_name, parts, unit_quaternion,
};
use crate::Error;

/// Targets per module before the program is split (a module of 2000 targets is about 250 kB of
/// text, well within a controller's program memory).
pub const TARGETS_PER_MODULE: usize = 2000;

const UNUSED: &str = "9E+09";

fn frame_text(f: &Frame) -> String {
    let q = unit_quaternion(f.orientation).unwrap_or([1.0, 0.0, 0.0, 0.0]);
    format!(
        "[[{},{},{}],[{},{},{},{}]]",
        fixed(f.position_mm[0], 3),
        fixed(f.position_mm[1], 3),
        fixed(f.position_mm[2], 3),
        fixed(q[0], 6),
        fixed(q[1], 6),
        fixed(q[2], 6),
        fixed(q[3], 6)
    )
}

/// The program set: the main module first.
pub(crate) fn write(
    path: &ProgramPath,
    arm: &SixAxisArm,
    per_file: usize,
) -> Result<Vec<(String, String)>, Error> {
    let id = identifier(super::Format::Rapid, &path.name);
    let chunks = parts(path, per_file);
    let n = chunks.len();
    let tool = format!(
        "PERS tooldata tWEye := [TRUE,{},[1,[0,0,1],[1,0,0,0],0,0,0]];",
        frame_text(&path.tool)
    );
    let wobj = match &path.mandrel {
        MandrelCoupling::Decoupled { .. } => format!(
            "PERS wobjdata wWWork := [FALSE,TRUE,\"\",{},[[0,0,0],[1,0,0,0]]];",
            frame_text(&path.work)
        ),
        MandrelCoupling::Coupled { axis } => format!(
            "PERS wobjdata wWWork := [FALSE,FALSE,\"{}\",{},[[0,0,0],[1,0,0,0]]];",
            axis.mechanical_unit.replace('"', ""),
            frame_text(&path.work)
        ),
    };
    let mut files = Vec::new();
    let mut main = String::new();
    let _ = writeln!(main, "MODULE {id}");
    let _ = writeln!(
        main,
        "  ! windcell path {}: {} targets{}",
        path.name.replace(['\n', '\r'], " "),
        path.targets.len(),
        if n > 1 {
            format!(", {n} modules loaded in turn from HOME:/{id}/")
        } else {
            String::new()
        }
    );
    let _ = writeln!(main, "  {tool}");
    let _ = writeln!(main, "  {wobj}");
    let mut first_index = 0;
    let mut part_texts = Vec::new();
    for (k, chunk) in chunks.iter().enumerate() {
        let name = part_name(&id, k, n);
        let body = part_body(path, arm, chunk, first_index, n > 1);
        first_index += chunk.len();
        part_texts.push((name, body));
    }
    if n == 1 {
        let (_, (decls, procs)) = part_texts.pop().unwrap_or_default();
        main.push_str(&decls);
        let _ = writeln!(main, "  PROC main()");
        main.push_str(&procs);
        let _ = writeln!(main, "  ENDPROC");
        let _ = writeln!(main, "ENDMODULE");
        files.push((format!("{id}.mod"), main));
        return Ok(files);
    }
    let _ = writeln!(main, "  PROC main()");
    let _ = writeln!(main, "    ConfL \\On;");
    for (name, _) in &part_texts {
        let _ = writeln!(main, "    Load \\Dynamic, \"HOME:/{id}/{name}.mod\";");
        let _ = writeln!(main, "    %\"{name}\"%;");
        let _ = writeln!(main, "    UnLoad \"HOME:/{id}/{name}.mod\";");
    }
    let _ = writeln!(main, "  ENDPROC");
    let _ = writeln!(main, "ENDMODULE");
    files.push((format!("{id}.mod"), main));
    for (name, (decls, procs)) in part_texts {
        let mut t = String::new();
        // A module and a routine may not share a name: the part module is `M` + its procedure.
        let _ = writeln!(t, "MODULE M{name}");
        t.push_str(&decls);
        let _ = writeln!(t, "  PROC {name}()");
        t.push_str(&procs);
        let _ = writeln!(t, "  ENDPROC");
        let _ = writeln!(t, "ENDMODULE");
        files.push((format!("{name}.mod"), t));
    }
    Ok(files)
}

/// The declarations and the procedure body of one module's targets.
fn part_body(
    path: &ProgramPath,
    arm: &SixAxisArm,
    targets: &[super::ProgramTarget],
    first_index: usize,
    local: bool,
) -> (String, String) {
    let storage = if local { "LOCAL CONST" } else { "CONST" };
    let mut decls = String::new();
    let mut body = String::new();
    let mut speeds: Vec<i64> = Vec::new();
    let mut zones: Vec<i64> = Vec::new();
    if first_index == 0 {
        let _ = writeln!(body, "    ConfL \\On;");
    }
    let sync = match path.mandrel {
        MandrelCoupling::Decoupled { sync } => Some(sync),
        MandrelCoupling::Coupled { .. } => None,
    };
    for (k, t) in targets.iter().enumerate() {
        let index = first_index + k + 1;
        let q = unit_quaternion(t.orientation).unwrap_or([1.0, 0.0, 0.0, 0.0]);
        let c = abb_conf(arm, &t.joints_deg);
        let eax_a = t.external_deg.map_or(UNUSED.to_string(), |e| fixed(e, 4));
        let _ = writeln!(
            decls,
            "  {storage} robtarget pW{index} := [[{},{},{}],[{},{},{},{}],[{},{},{},{}],[{eax_a},{UNUSED},{UNUSED},{UNUSED},{UNUSED},{UNUSED}]];",
            fixed(t.position_mm[0], 3),
            fixed(t.position_mm[1], 3),
            fixed(t.position_mm[2], 3),
            fixed(q[0], 6),
            fixed(q[1], 6),
            fixed(q[2], 6),
            fixed(q[3], 6),
            c.cf1,
            c.cf4,
            c.cf6,
            c.cfx
        );
        let zone = if t.zone_mm <= 0.0 || (t.sync && sync.is_some()) {
            "fine".to_string()
        } else {
            let z = (t.zone_mm * 10.0).round() as i64;
            let i = zones.iter().position(|v| *v == z).unwrap_or_else(|| {
                zones.push(z);
                zones.len() - 1
            });
            format!("zW{}", i + 1)
        };
        if first_index + k == 0 {
            let _ = writeln!(
                body,
                "    MoveJ pW{index}, v100, {zone}, tWEye \\WObj:=wWWork;"
            );
            continue;
        }
        let v = (t.speed_mm_s * 10.0).round().max(1.0) as i64;
        let si = speeds.iter().position(|s| *s == v).unwrap_or_else(|| {
            speeds.push(v);
            speeds.len() - 1
        });
        let time = if t.duration_s > 0.0 {
            format!(" \\T:={}", fixed(t.duration_s, 4))
        } else {
            String::new()
        };
        if let (true, Some(s)) = (t.sync, sync) {
            let _ = writeln!(body, "    SetDO doWc{}, 1;", s.start_output);
            let _ = writeln!(
                body,
                "    MoveL pW{index}, vW{}{time}, {zone}, tWEye \\WObj:=wWWork;",
                si + 1
            );
            let _ = writeln!(body, "    WaitDI diWc{}, 1;", s.in_position_input);
            let _ = writeln!(body, "    SetDO doWc{}, 0;", s.start_output);
            let _ = writeln!(body, "    WaitDI diWc{}, 0;", s.in_position_input);
        } else {
            let _ = writeln!(
                body,
                "    MoveL pW{index}, vW{}{time}, {zone}, tWEye \\WObj:=wWWork;",
                si + 1
            );
        }
    }
    let mut head = String::new();
    for (i, v) in speeds.iter().enumerate() {
        let _ = writeln!(
            head,
            "  {storage} speeddata vW{} := [{},500,5000,1000];",
            i + 1,
            fixed(*v as f64 / 10.0, 1)
        );
    }
    for (i, z) in zones.iter().enumerate() {
        let z = *z as f64 / 10.0;
        let _ = writeln!(
            head,
            "  {storage} zonedata zW{} := [FALSE,{},{},{},{},{},{}];",
            i + 1,
            fixed(z, 1),
            fixed(1.5 * z, 2),
            fixed(1.5 * z, 2),
            fixed(0.15 * z, 3),
            fixed(1.5 * z, 2),
            fixed(0.15 * z, 3)
        );
    }
    head.push_str(&decls);
    (head, body)
}

// ---------------------------------------------------------------------------------------------
// Reading

/// A value of a declaration or argument.
#[derive(Debug, Clone, PartialEq)]
enum Value {
    Num(f64),
    Str(String),
    Name(String),
    List(Vec<Value>),
}

impl Value {
    fn nums(&self, n: usize, what: &str, at: &Tok) -> Result<Vec<f64>, Error> {
        match self {
            Value::List(v) if v.len() == n => v
                .iter()
                .map(|x| match x {
                    Value::Num(f) => Ok(*f),
                    _ => Err(at.error(format!("{what}: expected {n} numbers"))),
                })
                .collect(),
            _ => Err(at.error(format!("{what}: expected a list of {n} numbers"))),
        }
    }

    fn list(&self, n: usize, what: &str, at: &Tok) -> Result<&[Value], Error> {
        match self {
            Value::List(v) if v.len() == n => Ok(v),
            _ => Err(at.error(format!("{what}: expected a list of {n} items"))),
        }
    }
}

fn value(c: &mut Cursor<'_>, depth: usize) -> Result<Value, Error> {
    c.skip_newlines();
    let t = c.peek();
    if depth > 8 {
        return Err(t.error("values nested too deep"));
    }
    match &t.kind {
        Kind::Punct("[") => {
            c.next();
            let mut items = Vec::new();
            loop {
                items.push(value(c, depth + 1)?);
                c.skip_newlines();
                if c.eat_punct(",") {
                    continue;
                }
                c.skip_newlines();
                c.expect_punct("]")?;
                return Ok(Value::List(items));
            }
        }
        Kind::Punct("-") | Kind::Punct("+") | Kind::Number(_) => Ok(Value::Num(c.number()?)),
        Kind::Str(s) => {
            c.next();
            Ok(Value::Str(s.clone()))
        }
        Kind::Ident(s) if !c.at_end() => {
            c.next();
            Ok(Value::Name(s.clone()))
        }
        _ => Err(t.error(format!("expected a value, found {}", t.shown()))),
    }
}

/// One argument of an instruction: its value and its switches (`\T:=2.5`, `\WObj:=w`, `\On`).
#[derive(Debug)]
struct Arg<'a> {
    value: Option<Value>,
    switches: Vec<(String, Option<Value>)>,
    at: &'a Tok,
}

fn switch(c: &mut Cursor<'_>, a: &mut Arg<'_>) -> Result<(), Error> {
    let (name, _) = c.ident()?;
    let v = if c.eat_punct(":=") {
        Some(value(c, 0)?)
    } else {
        None
    };
    a.switches.push((name, v));
    Ok(())
}

fn args<'a>(c: &mut Cursor<'a>) -> Result<Vec<Arg<'a>>, Error> {
    let mut out = Vec::new();
    c.skip_newlines();
    if c.eat_punct(";") {
        return Ok(out);
    }
    loop {
        c.skip_newlines();
        let mut a = Arg {
            value: None,
            switches: Vec::new(),
            at: c.peek(),
        };
        while c.eat_punct("\\") {
            switch(c, &mut a)?;
            c.skip_newlines();
        }
        if !c.peek().is_punct(",") && !c.peek().is_punct(";") {
            a.value = Some(value(c, 0)?);
        }
        c.skip_newlines();
        while c.eat_punct("\\") {
            switch(c, &mut a)?;
            c.skip_newlines();
        }
        out.push(a);
        if c.eat_punct(",") {
            continue;
        }
        c.expect_punct(";")?;
        return Ok(out);
    }
}

/// Instructions windcell's programs or a controller's editor may hold that change nothing the
/// reader reports (configuration monitoring, loading, messages, acceleration, singularity).
const IGNORED: &[&str] = &[
    "ConfL",
    "ConfJ",
    "Load",
    "UnLoad",
    "TPWrite",
    "TPErase",
    "WaitTime",
    "AccSet",
    "VelSet",
    "SingArea",
    "ActUnit",
    "DeactUnit",
    "PathAccLim",
    "RETURN",
    "Stop",
    "EOffsOff",
];

struct Decl {
    kind: String,
    value: Value,
    at: usize,
}

/// Parses one module.
pub(crate) fn parse(text: &str) -> Result<Unit, Error> {
    let toks = lex(text, 1, Some('!'))?;
    let mut c = Cursor::new(&toks);
    c.skip_newlines();
    // The `%%%` header of a module saved by older controllers.
    let percents = |c: &Cursor<'_>| {
        c.peek().is_punct("%") && c.peek_at(1).is_punct("%") && c.peek_at(2).is_punct("%")
    };
    if percents(&c) {
        c.pos += 3;
        while !(c.at_end() || percents(&c)) {
            c.next();
        }
        if c.at_end() {
            return Err(toks[0].error("the %%% header is not closed"));
        }
        c.pos += 3;
        c.skip_newlines();
    }
    c.expect_ident_word("MODULE")?;
    let _ = c.ident()?;
    if c.eat_punct("(") {
        while !c.at_end() && !c.peek().is_punct(")") {
            c.next();
        }
        c.expect_punct(")")?;
    }
    let mut decls: HashMap<String, Decl> = HashMap::new();
    let mut raw_routines: Vec<(String, usize, usize)> = Vec::new();
    loop {
        c.skip_newlines();
        if c.at_end() {
            return Err(c.peek().error("ENDMODULE is missing"));
        }
        let t = c.peek();
        if c.eat_ident("ENDMODULE") {
            c.skip_newlines();
            if !c.at_end() {
                let t = c.peek();
                return Err(t.error(format!("{} after ENDMODULE", t.shown())));
            }
            break;
        }
        c.eat_ident("LOCAL");
        c.eat_ident("TASK");
        if c.eat_ident("CONST") || c.eat_ident("PERS") || c.eat_ident("VAR") {
            let (kind, _) = c.ident()?;
            let name_at = c.pos;
            let (name, _) = c.ident()?;
            if c.eat_punct("{") {
                while !c.at_end() && !c.peek().is_punct("}") {
                    c.next();
                }
                c.expect_punct("}")?;
            }
            let v = if c.eat_punct(":=") {
                value(&mut c, 0)?
            } else {
                Value::List(Vec::new())
            };
            c.skip_newlines();
            c.expect_punct(";")?;
            decls.insert(
                name.to_ascii_uppercase(),
                Decl {
                    kind: kind.to_ascii_lowercase(),
                    value: v,
                    at: name_at,
                },
            );
            continue;
        }
        let (word, _) = c.ident().map_err(|_| {
            t.error(format!(
                "expected a declaration, PROC or ENDMODULE, found {}",
                t.shown()
            ))
        })?;
        let end = match word.to_ascii_uppercase().as_str() {
            "PROC" => "ENDPROC",
            "FUNC" => "ENDFUNC",
            "TRAP" => "ENDTRAP",
            _ => {
                return Err(t.error(format!(
                    "expected a declaration, PROC or ENDMODULE, found {}",
                    t.shown()
                )));
            }
        };
        if end == "ENDFUNC" {
            let _ = c.ident()?; // the return type
        }
        let (name, _) = c.ident()?;
        if end != "ENDTRAP" {
            c.expect_punct("(")?;
            while !c.at_end() && !c.peek().is_punct(")") {
                c.next();
            }
            c.expect_punct(")")?;
        }
        let start = c.pos;
        while !c.at_end() && !c.peek().is_ident(end) {
            c.next();
        }
        if c.at_end() {
            return Err(t.error(format!("{end} is missing")));
        }
        let stop = c.pos;
        c.next();
        if end == "ENDPROC" {
            raw_routines.push((name, start, stop));
        }
    }
    let mut unit = Unit::default();
    for (name, d) in &decls {
        let at = &toks[d.at];
        match (d.kind.as_str(), name.as_str()) {
            ("tooldata", _) if unit.tool.is_none() => {
                let l = d.value.list(3, "tooldata", at)?;
                unit.tool = Some(pose(&l[1], "tooldata tframe", at)?);
            }
            ("wobjdata", _) if unit.work.is_none() => {
                let l = d.value.list(5, "wobjdata", at)?;
                unit.work = Some(pose(&l[3], "wobjdata uframe", at)?);
            }
            _ => {}
        }
    }
    for (name, start, stop) in raw_routines {
        let body = routine(&toks[start..stop], &decls, &toks)?;
        unit.routines.push(Routine { name, body });
    }
    Ok(unit)
}

/// A quaternion as printed, normalised with its sign kept (a negative `q1` stays negative, so a
/// checker can see it), when its norm is within 1e-4 of 1: printed with 6 decimals its norm is
/// off by up to 1e-6, and the controller's editor prints fewer digits still.
fn printed_quaternion(q: &[f64]) -> Option<[f64; 4]> {
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    (n.is_finite() && (n - 1.0).abs() < 1e-4).then(|| [q[0] / n, q[1] / n, q[2] / n, q[3] / n])
}

fn pose(v: &Value, what: &str, at: &Tok) -> Result<Frame, Error> {
    let l = v.list(2, what, at)?;
    let p = l[0].nums(3, what, at)?;
    let q = l[1].nums(4, what, at)?;
    let q = printed_quaternion(&q)
        .ok_or_else(|| at.error(format!("{what}: the quaternion is not of unit length")))?;
    Ok(Frame {
        position_mm: [p[0], p[1], p[2]],
        orientation: q,
    })
}

/// A predefined `vN`/`zN` data name's number.
fn predefined(name: &str, prefix: char) -> Option<f64> {
    let rest = name
        .strip_prefix(prefix)
        .or_else(|| name.strip_prefix(prefix.to_ascii_uppercase()))?;
    if rest.eq_ignore_ascii_case("max") && prefix == 'v' {
        return Some(5000.0);
    }
    let n: f64 = rest.parse().ok()?;
    Some(if prefix == 'z' && n == 0.0 { 0.3 } else { n })
}

fn signal_number(name: &str, at: &Tok) -> Result<u16, Error> {
    let digits: String = name
        .chars()
        .rev()
        .take_while(char::is_ascii_digit)
        .collect::<Vec<_>>()
        .into_iter()
        .rev()
        .collect();
    digits
        .parse()
        .map_err(|_| at.error(format!("signal {name} does not end in its number")))
}

fn routine(toks: &[Tok], decls: &HashMap<String, Decl>, all: &[Tok]) -> Result<Vec<Item>, Error> {
    let mut toks = toks.to_vec();
    // A closing line end so that the cursor never runs past the slice's last statement.
    toks.push(Tok {
        kind: Kind::Newline,
        line: toks.last().map_or(1, |t| t.line),
        column: 1,
    });
    let mut c = Cursor::new(&toks);
    let mut out = Vec::new();
    let _ = all;
    loop {
        c.skip_newlines();
        if c.pos >= toks.len() - 1 {
            break;
        }
        let t = c.peek();
        if c.eat_punct("%") {
            let s = c.next();
            let Kind::Str(name) = &s.kind else {
                return Err(s.error(format!(
                    "expected a procedure name in quotes, found {}",
                    s.shown()
                )));
            };
            c.expect_punct("%")?;
            c.skip_newlines();
            c.expect_punct(";")?;
            out.push(Item::Call {
                name: name.clone(),
                line: t.line,
                column: t.column,
            });
            continue;
        }
        let (word, _) = c
            .ident()
            .map_err(|_| t.error(format!("expected an instruction, found {}", t.shown())))?;
        let a = args(&mut c)?;
        let upper = word.to_ascii_uppercase();
        match upper.as_str() {
            "MOVEL" | "MOVEJ" => out.push(Item::Step(Step::Move(movement(t, &upper, &a, decls)?))),
            "SETDO" | "WAITDI" => {
                let [sig, v] = a.as_slice() else {
                    return Err(t.error(format!("{word} takes a signal and a value")));
                };
                let Some(Value::Name(s)) = &sig.value else {
                    return Err(sig.at.error("expected a signal name"));
                };
                let number = signal_number(s, sig.at)?;
                let on = match &v.value {
                    Some(Value::Num(x)) if *x == 0.0 || *x == 1.0 => *x == 1.0,
                    Some(Value::Name(n)) if n.eq_ignore_ascii_case("high") => true,
                    Some(Value::Name(n)) if n.eq_ignore_ascii_case("low") => false,
                    _ => return Err(v.at.error("expected 0 or 1")),
                };
                let step = if upper == "SETDO" {
                    Step::Output {
                        file: String::new(),
                        line: t.line,
                        number,
                        on,
                    }
                } else {
                    Step::Wait {
                        file: String::new(),
                        line: t.line,
                        number,
                        on,
                    }
                };
                out.push(Item::Step(step));
            }
            _ if IGNORED.iter().any(|w| w.eq_ignore_ascii_case(&word)) => {}
            _ if a.is_empty() => out.push(Item::Call {
                name: word,
                line: t.line,
                column: t.column,
            }),
            _ => {
                return Err(t.error(format!(
                    "instruction {word} is not one a winding program uses"
                )));
            }
        }
    }
    Ok(out)
}

fn movement(
    t: &Tok,
    upper: &str,
    a: &[Arg<'_>],
    decls: &HashMap<String, Decl>,
) -> Result<ReadTarget, Error> {
    let lookup = |name: &str, kind: &str, at: &Tok| lookup(decls, name, kind, at);
    if a.len() != 4 {
        return Err(t.error(format!(
            "{upper} takes a target, a speed, a zone and a tool ({} arguments found)",
            a.len()
        )));
    }
    let target = match &a[0].value {
        Some(Value::Name(n)) => lookup(n, "robtarget", a[0].at)?.clone(),
        Some(v @ Value::List(_)) => v.clone(),
        _ => return Err(a[0].at.error("expected a robtarget")),
    };
    let at = a[0].at;
    let l = target.list(4, "robtarget", at)?;
    let p = l[0].nums(3, "robtarget trans", at)?;
    let q = l[1].nums(4, "robtarget rot", at)?;
    let orientation = printed_quaternion(&q)
        .ok_or_else(|| at.error("robtarget rot: the quaternion is not of unit length"))?;
    let cf = l[2].nums(4, "robtarget robconf", at)?;
    if cf.iter().any(|v| v.fract() != 0.0 || v.abs() > 1e6) {
        return Err(at.error("robtarget robconf: expected whole numbers"));
    }
    let ext = l[3].nums(6, "robtarget extax", at)?;
    let external_deg = if ext[0] >= 8.9e9 { None } else { Some(ext[0]) };
    let mut speed_mm_s = match &a[1].value {
        Some(Value::Name(n)) => match predefined(n, 'v') {
            Some(v) => Some(v),
            None => {
                let sv = lookup(n, "speeddata", a[1].at)?;
                Some(sv.nums(4, "speeddata", a[1].at)?[0])
            }
        },
        Some(v @ Value::List(_)) => Some(v.nums(4, "speeddata", a[1].at)?[0]),
        _ => return Err(a[1].at.error("expected a speeddata")),
    };
    let mut duration_s = None;
    for (s, v) in &a[1].switches {
        match (s.to_ascii_uppercase().as_str(), v) {
            ("T", Some(Value::Num(x))) if *x > 0.0 => duration_s = Some(*x),
            ("V", Some(Value::Num(x))) if *x > 0.0 => speed_mm_s = Some(*x),
            _ => {
                return Err(a[1].at.error(format!(
                    "speed switch \\{s} is not \\T or \\V with a positive number"
                )));
            }
        }
    }
    let mut zone = match &a[2].value {
        Some(Value::Name(n)) if n.eq_ignore_ascii_case("fine") => Zone::Fine,
        Some(Value::Name(n)) => match predefined(n, 'z') {
            Some(z) => Zone::Distance(z),
            None => zone_of(lookup(n, "zonedata", a[2].at)?, a[2].at)?,
        },
        Some(v @ Value::List(_)) => zone_of(v, a[2].at)?,
        _ => return Err(a[2].at.error("expected a zonedata")),
    };
    for (s, v) in &a[2].switches {
        match (s.to_ascii_uppercase().as_str(), v) {
            ("Z", Some(Value::Num(x))) if *x >= 0.0 => zone = Zone::Distance(*x),
            ("INPOS", _) => {}
            _ => {
                return Err(a[2]
                    .at
                    .error(format!("zone switch \\{s} is not \\Z with a number")));
            }
        }
    }
    match &a[3].value {
        Some(Value::Name(_)) => {}
        _ => return Err(a[3].at.error("expected a tooldata name")),
    }
    Ok(ReadTarget {
        file: String::new(),
        line: t.line,
        motion: if upper == "MOVEJ" {
            Motion::Joint
        } else {
            Motion::Linear
        },
        position_mm: [p[0], p[1], p[2]],
        orientation,
        config: ConfigData::Abb(AbbConf {
            cf1: cf[0] as i32,
            cf4: cf[1] as i32,
            cf6: cf[2] as i32,
            cfx: cf[3] as i32,
        }),
        external_deg,
        speed_mm_s,
        duration_s,
        zone,
    })
}

fn lookup<'d>(
    decls: &'d HashMap<String, Decl>,
    name: &str,
    kind: &str,
    at: &Tok,
) -> Result<&'d Value, Error> {
    match decls.get(&name.to_ascii_uppercase()) {
        Some(d) if d.kind == kind => Ok(&d.value),
        Some(d) => Err(at.error(format!("{name} is a {}, not a {kind}", d.kind))),
        None => Err(at.error(format!("{kind} {name} is not declared in this module"))),
    }
}

fn zone_of(v: &Value, at: &Tok) -> Result<Zone, Error> {
    let l = v.list(7, "zonedata", at)?;
    let fine = matches!(&l[0], Value::Name(n) if n.eq_ignore_ascii_case("TRUE"));
    let z = l[1..].iter().map(|x| match x {
        Value::Num(f) => Ok(*f),
        _ => Err(at.error("zonedata: expected numbers after finep")),
    });
    let z: Vec<f64> = z.collect::<Result<_, _>>()?;
    Ok(if fine {
        Zone::Fine
    } else {
        Zone::Distance(z[0])
    })
}
