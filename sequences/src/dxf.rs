//! AutoCAD DXF (ASCII) drawings: the fibre paths and spine profiles of seed 001 §5.5 ("the end
//! points of the segments ... were stored in a .DXF file format") and §5.6 ("the .DXF file of the
//! path and the spine profile").
//!
//! A DXF file is a sequence of group-code/value pairs, each on two lines: an integer code, then
//! its value. Only the ENTITIES section is read; other sections are skipped. POINT, LINE,
//! POLYLINE (with its VERTEX … SEQEND entities) and LWPOLYLINE become [`Entity`] values holding
//! 3D points in drawing units in file order, with their layer and the place of every coordinate;
//! every other entity is skipped. From the HEADER section only `$INSUNITS` is read: the drawing's
//! units ([`Units`]); [`Drawing::path`] and [`Drawing::profile`] give millimetres. Errors name
//! the line and column of the offending code or value.
//!
//! [`Drawing::write`] writes the same four entities (and `$INSUNITS` when the drawing has units)
//! in a minimal file, so that parsing, writing and parsing again gives an equal drawing. The
//! format is documented in `docs/file-formats.md` ("DXF").

use std::path::Path;

use crate::Error;
use crate::syntax::number;

/// The kind of entity a polyline came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A POINT: one point.
    Point,
    /// A LINE: two points.
    Line,
    /// A POLYLINE with VERTEX entities (2D, 3D or spline-fit).
    Polyline,
    /// A LWPOLYLINE (planar, one elevation).
    LwPolyline,
}

impl Kind {
    /// The DXF entity name (`POINT`, `LINE`, `POLYLINE`, `LWPOLYLINE`).
    pub fn name(self) -> &'static str {
        match self {
            Kind::Point => "POINT",
            Kind::Line => "LINE",
            Kind::Polyline => "POLYLINE",
            Kind::LwPolyline => "LWPOLYLINE",
        }
    }
}

/// Where a value sits in the file: 1-based line, and the 1-based column where its text starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Place {
    /// 1-based line.
    pub line: usize,
    /// 1-based column.
    pub column: usize,
}

/// The drawing units of `$INSUNITS` (HEADER section, group code 70) that windcell reads. A
/// drawing without `$INSUNITS`, or with `0` ("unitless"), is read in millimetres.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Units {
    /// `0`: no units given; read as millimetres.
    Unitless,
    /// `1`: inches (25.4 mm).
    Inches,
    /// `2`: feet (304.8 mm).
    Feet,
    /// `4`: millimetres.
    Millimetres,
    /// `5`: centimetres.
    Centimetres,
    /// `6`: metres.
    Metres,
}

impl Units {
    /// Every unit windcell reads.
    pub const ALL: [Units; 6] = [
        Units::Unitless,
        Units::Inches,
        Units::Feet,
        Units::Millimetres,
        Units::Centimetres,
        Units::Metres,
    ];

    /// The `$INSUNITS` code.
    pub fn code(self) -> i64 {
        match self {
            Units::Unitless => 0,
            Units::Inches => 1,
            Units::Feet => 2,
            Units::Millimetres => 4,
            Units::Centimetres => 5,
            Units::Metres => 6,
        }
    }

    /// The unit of a `$INSUNITS` code; `None` for a code windcell does not read.
    pub fn from_code(code: i64) -> Option<Self> {
        Units::ALL.into_iter().find(|u| u.code() == code)
    }

    /// Millimetres per drawing unit (1 for [`Units::Unitless`]).
    pub fn mm_per_unit(self) -> f64 {
        match self {
            Units::Unitless | Units::Millimetres => 1.0,
            Units::Inches => 25.4,
            Units::Feet => 304.8,
            Units::Centimetres => 10.0,
            Units::Metres => 1000.0,
        }
    }

    /// The unit's name in messages (`millimetres`).
    pub fn name(self) -> &'static str {
        match self {
            Units::Unitless => "unitless (read as millimetres)",
            Units::Inches => "inches",
            Units::Feet => "feet",
            Units::Millimetres => "millimetres",
            Units::Centimetres => "centimetres",
            Units::Metres => "metres",
        }
    }
}

/// One entity of the ENTITIES section as a polyline of 3D points.
///
/// `places` records where each coordinate was read; it takes no part in equality (a drawing
/// written and read again is equal to the one written).
#[derive(Debug, Clone)]
pub struct Entity {
    /// What it was in the file.
    pub kind: Kind,
    /// Its layer (group code 8; `0` when absent).
    pub layer: String,
    /// Its points in world coordinates, drawing units, in file order.
    pub points: Vec<[f64; 3]>,
    /// A closed POLYLINE or LWPOLYLINE (flag bit 1): the last point joins the first.
    pub closed: bool,
    /// For a parsed entity, one entry per point: where its x, y and z values were read (a
    /// coordinate the file leaves out, such as a default z, is placed at the entity's name).
    /// Empty for an entity built in code.
    pub places: Vec<[Place; 3]>,
}

impl PartialEq for Entity {
    fn eq(&self, other: &Self) -> bool {
        self.kind == other.kind
            && self.layer == other.layer
            && self.points == other.points
            && self.closed == other.closed
    }
}

/// The entities of a DXF drawing that windcell reads, in file order, and its units.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Drawing {
    /// POINT, LINE, POLYLINE and LWPOLYLINE entities.
    pub entities: Vec<Entity>,
    /// `$INSUNITS` of the HEADER section; `None` when the drawing does not give it (read as
    /// millimetres).
    pub units: Option<Units>,
}

/// One point of a drawing's path in millimetres, with where its coordinates were read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathPoint {
    /// The point, millimetres (drawing units scaled by `$INSUNITS`).
    pub mm: [f64; 3],
    /// Where its x, y and z values were read; `None` for an entity built in code.
    pub places: Option<[Place; 3]>,
}

/// One group-code/value pair and where its value sits.
#[derive(Debug, Clone, Copy)]
struct Pair<'a> {
    code: i32,
    value: &'a str,
    /// 1-based line of the code.
    code_line: usize,
    /// 1-based line of the value.
    line: usize,
    /// 1-based column where the value's text starts.
    column: usize,
}

impl Pair<'_> {
    fn error(&self, message: impl Into<String>) -> Error {
        Error::at(self.line, self.column, message)
    }

    fn place(&self) -> Place {
        Place {
            line: self.line,
            column: self.column,
        }
    }

    fn is(&self, code: i32, value: &str) -> bool {
        self.code == code && self.value == value
    }

    fn f64(&self) -> Result<f64, Error> {
        match self.value.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => Err(self.error(format!(
                "group code {} holds `{}`, which is not a finite number",
                self.code, self.value
            ))),
            Err(_) => Err(self.error(format!(
                "group code {} expects a number, found `{}`",
                self.code, self.value
            ))),
        }
    }

    fn int(&self) -> Result<i64, Error> {
        self.value.parse::<i64>().map_err(|_| {
            self.error(format!(
                "group code {} expects an integer, found `{}`",
                self.code, self.value
            ))
        })
    }
}

/// Splits `text` into pairs up to and including `0 EOF`. Values are trimmed (CR, spaces).
fn pairs(text: &str) -> Result<Vec<Pair<'_>>, Error> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    // `lines` ends lines at LF or CRLF and drops the empty piece after a final line break.
    let mut lines = text.lines().enumerate().map(|(i, raw)| {
        let trimmed = raw.trim_start();
        let column = raw[..raw.len() - trimmed.len()].chars().count() + 1;
        (i + 1, trimmed.trim_end(), column)
    });
    let mut out = Vec::new();
    let mut last_line = 0;
    while let Some((code_line, code_text, code_column)) = lines.next() {
        let code = code_text.parse::<i32>().map_err(|_| {
            if code_text.is_empty() {
                Error::at(
                    code_line,
                    code_column,
                    "expected a group code, found an empty line",
                )
            } else {
                Error::at(
                    code_line,
                    code_column,
                    format!("expected a group code (an integer), found `{code_text}`"),
                )
            }
        })?;
        let Some((line, value, column)) = lines.next() else {
            return Err(Error::at(
                code_line + 1,
                1,
                format!(
                    "group code {code} at line {code_line} has no value (the file is truncated)"
                ),
            ));
        };
        last_line = line;
        let pair = Pair {
            code,
            value,
            code_line,
            line,
            column,
        };
        out.push(pair);
        if pair.is(0, "EOF") {
            return Ok(out);
        }
    }
    Err(Error::at(
        last_line + 1,
        1,
        "the file ends without `0 EOF` (it is truncated)",
    ))
}

impl Drawing {
    /// Parses the text of an ASCII DXF file (LF or CRLF line endings).
    pub fn parse(text: &str) -> Result<Self, Error> {
        let pairs = pairs(text)?;
        let mut entities = Vec::new();
        let mut units = None;
        let mut i = 0;
        while let Some(pair) = pairs.get(i) {
            if pair.is(0, "EOF") {
                break;
            }
            if pair.code == 999 {
                i += 1;
                continue;
            }
            if !pair.is(0, "SECTION") {
                return Err(pair.error(format!(
                    "expected `0 SECTION`, found group code {} `{}`",
                    pair.code, pair.value
                )));
            }
            let name = match pairs.get(i + 1) {
                Some(p) if p.code == 2 => p,
                Some(p) => {
                    return Err(p.error(format!(
                        "expected the section name (group code 2), found group code {}",
                        p.code
                    )));
                }
                None => return Err(pair.error("section without a name")),
            };
            let end = pairs[i + 2..]
                .iter()
                .position(|p| p.is(0, "ENDSEC") || p.is(0, "EOF"))
                .map(|k| k + i + 2)
                .filter(|&k| pairs[k].value == "ENDSEC")
                .ok_or_else(|| {
                    name.error(format!(
                        "section {} has no `0 ENDSEC` (the file is truncated)",
                        name.value
                    ))
                })?;
            match name.value {
                "ENTITIES" => read_entities(&pairs[i + 2..end], &mut entities)?,
                "HEADER" => units = read_units(&pairs[i + 2..end])?.or(units),
                _ => {}
            }
            i = end + 1;
        }
        Ok(Drawing { entities, units })
    }

    /// Millimetres per drawing unit: from `$INSUNITS`, 1 when the drawing does not give it.
    pub fn mm_per_unit(&self) -> f64 {
        self.units.map_or(1.0, Units::mm_per_unit)
    }

    /// Reads and parses a DXF file; errors name the file.
    pub fn load(path: &Path) -> Result<Self, Error> {
        let bytes = crate::source::read_bytes(path, crate::source::MAX_DXF_BYTES)?;
        // Old drawings may hold Latin-1 text in names; coordinates are ASCII either way.
        let text = String::from_utf8_lossy(&bytes);
        Drawing::parse(&text).map_err(|e| e.in_file(path))
    }

    /// Writes an ENTITIES-only ASCII DXF (LF line endings) that parses back to an equal drawing.
    ///
    /// Fails for a layer name that is empty, has surrounding spaces or a line break, for a LINE
    /// without exactly two points, a POINT without exactly one, a polyline without points, or a
    /// LWPOLYLINE whose points do not share one elevation.
    pub fn write(&self) -> Result<String, Error> {
        let mut out = String::new();
        let mut pair = |code: i32, value: &str| {
            out.push_str(&format!("{code:>3}\n{value}\n"));
        };
        if let Some(units) = self.units {
            pair(0, "SECTION");
            pair(2, "HEADER");
            pair(9, "$INSUNITS");
            pair(70, &units.code().to_string());
            pair(0, "ENDSEC");
        }
        pair(0, "SECTION");
        pair(2, "ENTITIES");
        for (index, e) in self.entities.iter().enumerate() {
            let what = || format!("entity {} ({})", index + 1, e.kind.name());
            if e.layer.is_empty() || e.layer.trim() != e.layer || e.layer.contains(['\n', '\r']) {
                return Err(Error::content(format!(
                    "{}: layer name `{}` cannot be written",
                    what(),
                    e.layer
                )));
            }
            let expected = match e.kind {
                Kind::Point => Some(1),
                Kind::Line => Some(2),
                Kind::Polyline | Kind::LwPolyline => None,
            };
            if expected.is_some_and(|n| n != e.points.len()) || e.points.is_empty() {
                return Err(Error::content(format!(
                    "{} has {} points",
                    what(),
                    e.points.len()
                )));
            }
            let xyz = |pair: &mut dyn FnMut(i32, &str), base: i32, p: &[f64; 3]| {
                pair(base, &number(p[0]));
                pair(base + 10, &number(p[1]));
                pair(base + 20, &number(p[2]));
            };
            let closed = if e.closed { 1 } else { 0 };
            match e.kind {
                Kind::Point => {
                    pair(0, "POINT");
                    pair(8, &e.layer);
                    xyz(&mut pair, 10, &e.points[0]);
                }
                Kind::Line => {
                    pair(0, "LINE");
                    pair(8, &e.layer);
                    xyz(&mut pair, 10, &e.points[0]);
                    xyz(&mut pair, 11, &e.points[1]);
                }
                Kind::Polyline => {
                    pair(0, "POLYLINE");
                    pair(8, &e.layer);
                    pair(66, "1");
                    xyz(&mut pair, 10, &[0.0; 3]);
                    // 8 = 3D polyline, 1 = closed.
                    pair(70, &(8 + closed).to_string());
                    for p in &e.points {
                        pair(0, "VERTEX");
                        pair(8, &e.layer);
                        xyz(&mut pair, 10, p);
                        // 32 = 3D polyline vertex.
                        pair(70, "32");
                    }
                    pair(0, "SEQEND");
                    pair(8, &e.layer);
                }
                Kind::LwPolyline => {
                    let z = e.points[0][2];
                    if e.points.iter().any(|p| p[2] != z) {
                        return Err(Error::content(format!(
                            "{} is not planar: its points do not share one elevation",
                            what()
                        )));
                    }
                    pair(0, "LWPOLYLINE");
                    pair(8, &e.layer);
                    pair(90, &e.points.len().to_string());
                    pair(70, &closed.to_string());
                    pair(38, &number(z));
                    for p in &e.points {
                        pair(10, &number(p[0]));
                        pair(20, &number(p[1]));
                    }
                }
            }
        }
        pair(0, "ENDSEC");
        pair(0, "EOF");
        Ok(out)
    }

    /// The entities on `layer` (all of them for `None`).
    fn on<'a>(&'a self, layer: Option<&'a str>) -> impl Iterator<Item = &'a Entity> + 'a {
        self.entities
            .iter()
            .filter(move |e| layer.is_none_or(|l| e.layer == l))
    }

    /// The fibre path the drawing holds (on `layer`, or anywhere), in millimetres: its one
    /// POLYLINE or LWPOLYLINE (a closed one ends back at its first point); failing that, its
    /// POINTs in file order, as the thesis exported segment end points from AutoCAD (seed 001
    /// §5.5, Fig 5.8); failing that, a chain of LINEs each starting where the previous one ended
    /// (within 1 µm of drawing units). At least two points.
    pub fn path(&self, layer: Option<&str>) -> Result<Vec<[f64; 3]>, Error> {
        Ok(self.path_points(layer)?.into_iter().map(|p| p.mm).collect())
    }

    /// [`Drawing::path`] with the place of every coordinate in the file.
    pub fn path_points(&self, layer: Option<&str>) -> Result<Vec<PathPoint>, Error> {
        let place = layer.map_or(String::new(), |l| format!(" on layer `{l}`"));
        let polylines: Vec<&Entity> = self
            .on(layer)
            .filter(|e| matches!(e.kind, Kind::Polyline | Kind::LwPolyline))
            .collect();
        let points: Vec<(&Entity, usize)> = match polylines.as_slice() {
            [one] => {
                let mut points: Vec<(&Entity, usize)> =
                    (0..one.points.len()).map(|k| (*one, k)).collect();
                if one.closed && !one.points.is_empty() {
                    points.push((*one, 0));
                }
                points
            }
            [] => {
                let points: Vec<(&Entity, usize)> = self
                    .on(layer)
                    .filter(|e| e.kind == Kind::Point)
                    .flat_map(|e| (0..e.points.len()).map(move |k| (e, k)))
                    .collect();
                if points.is_empty() {
                    line_chain(self.on(layer).filter(|e| e.kind == Kind::Line), &place)?
                } else {
                    points
                }
            }
            many => {
                return Err(Error::content(format!(
                    "the drawing has {} polylines{place}; a path is one polyline (choose a layer)",
                    many.len()
                )));
            }
        };
        if points.len() < 2 {
            return Err(Error::content(format!(
                "the drawing has no path{place}: it needs a polyline, POINTs or LINEs with at \
                 least two points"
            )));
        }
        let scale = self.mm_per_unit();
        Ok(points
            .into_iter()
            .map(|(e, k)| PathPoint {
                mm: e.points[k].map(|c| c * scale),
                places: e.places.get(k).copied(),
            })
            .collect())
    }

    /// The spine profile the drawing holds: its path (see [`Drawing::path`], millimetres) read as
    /// `(height_mm, offset_mm)` = the drawing's `(x, y)`, heights strictly increasing (seed 001
    /// §6.4, Table 6.1: offsets of the spine against the distance along the mandrel).
    pub fn profile(&self, layer: Option<&str>) -> Result<Vec<(f64, f64)>, Error> {
        let points = self.path(layer)?;
        let mut out = Vec::with_capacity(points.len());
        for (index, p) in points.iter().enumerate() {
            if let Some(&(previous, _)) = out.last()
                && p[0] <= previous
            {
                return Err(Error::content(format!(
                    "spine profile point {} at height {} mm does not rise above the previous one",
                    index + 1,
                    p[0]
                )));
            }
            out.push((p[0], p[1]));
        }
        Ok(out)
    }
}

/// The points of LINEs joined end to start, as (entity, point index) pairs.
fn line_chain<'a>(
    lines: impl Iterator<Item = &'a Entity>,
    place: &str,
) -> Result<Vec<(&'a Entity, usize)>, Error> {
    let mut out: Vec<(&'a Entity, usize)> = Vec::new();
    for (index, line) in lines.enumerate() {
        let [start, _] = line.points[..] else {
            continue;
        };
        if let Some(&(e, k)) = out.last() {
            let last = e.points[k];
            let gap = (0..3)
                .map(|k| (last[k] - start[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            if gap > 1e-3 {
                return Err(Error::content(format!(
                    "line {} {place} starts {gap:.3} mm away from where the previous line ends",
                    index + 1
                )));
            }
        } else {
            out.push((line, 0));
        }
        out.push((line, 1));
    }
    Ok(out)
}

/// `$INSUNITS` of the HEADER section's pairs, if it is there.
fn read_units(pairs: &[Pair<'_>]) -> Result<Option<Units>, Error> {
    let Some(k) = pairs.iter().position(|p| p.is(9, "$INSUNITS")) else {
        return Ok(None);
    };
    let value = match pairs.get(k + 1) {
        Some(p) if p.code == 70 => p,
        Some(p) => {
            return Err(p.error(format!(
                "$INSUNITS expects group code 70, found group code {}",
                p.code
            )));
        }
        None => return Err(pairs[k].error("$INSUNITS has no value")),
    };
    let code = value.int()?;
    Units::from_code(code).map(Some).ok_or_else(|| {
        value.error(format!(
            "$INSUNITS {code} is a unit windcell does not read (0 unitless, 1 inches, 2 feet, \
             4 millimetres, 5 centimetres, 6 metres)"
        ))
    })
}

/// Reads the entities between `2 ENTITIES` and `0 ENDSEC`.
fn read_entities(pairs: &[Pair<'_>], out: &mut Vec<Entity>) -> Result<(), Error> {
    let mut i = 0;
    while let Some(head) = pairs.get(i) {
        if head.code == 999 {
            i += 1;
            continue;
        }
        if head.code != 0 {
            return Err(head.error(format!(
                "expected an entity (group code 0), found group code {}",
                head.code
            )));
        }
        let body_end = next_entity(pairs, i + 1);
        let body = &pairs[i + 1..body_end];
        i = body_end;
        match head.value {
            "POINT" => {
                let (point, places) = xyz(head, body, 10)?;
                out.push(Entity {
                    kind: Kind::Point,
                    layer: layer(body),
                    points: vec![point],
                    closed: false,
                    places: vec![places],
                });
            }
            "LINE" => {
                let (start, start_places) = xyz(head, body, 10)?;
                let (end, end_places) = xyz(head, body, 11)?;
                out.push(Entity {
                    kind: Kind::Line,
                    layer: layer(body),
                    points: vec![start, end],
                    closed: false,
                    places: vec![start_places, end_places],
                });
            }
            "LWPOLYLINE" => out.push(lwpolyline(head, body)?),
            "POLYLINE" => {
                let (entity, next) = polyline(head, body, pairs, i)?;
                i = next;
                out.extend(entity);
            }
            _ => {}
        }
    }
    Ok(())
}

/// The index of the next code-0 pair at or after `from`.
fn next_entity(pairs: &[Pair<'_>], from: usize) -> usize {
    pairs
        .get(from..)
        .and_then(|rest| rest.iter().position(|p| p.code == 0))
        .map_or(pairs.len(), |k| k + from)
}

fn layer(body: &[Pair<'_>]) -> String {
    body.iter()
        .find(|p| p.code == 8)
        .map_or_else(|| "0".to_string(), |p| p.value.to_string())
}

/// The point of codes `base`, `base + 10`, `base + 20` (z defaults to 0, placed at `head`) and
/// where each coordinate was read.
fn xyz(head: &Pair<'_>, body: &[Pair<'_>], base: i32) -> Result<([f64; 3], [Place; 3]), Error> {
    let mut out = [0.0; 3];
    let mut places = [head.place(); 3];
    for (k, slot) in out.iter_mut().enumerate() {
        let code = base + 10 * k as i32;
        match body.iter().rfind(|p| p.code == code) {
            Some(p) => {
                *slot = p.f64()?;
                places[k] = p.place();
            }
            None if k == 2 => {}
            None => {
                return Err(Error::at(
                    head.line,
                    head.column,
                    format!(
                        "{} at line {} has no group code {code} ({} coordinate)",
                        head.value,
                        head.code_line,
                        ["x", "y", "z"][k]
                    ),
                ));
            }
        }
    }
    Ok((out, places))
}

fn flags(body: &[Pair<'_>]) -> Result<i64, Error> {
    body.iter().rfind(|p| p.code == 70).map_or(Ok(0), Pair::int)
}

/// Refuses object coordinate systems other than the world's (group codes 210/220/230).
fn world_extrusion(head: &Pair<'_>, body: &[Pair<'_>]) -> Result<(), Error> {
    for (code, want) in [(210, 0.0), (220, 0.0), (230, 1.0)] {
        if let Some(p) = body.iter().rfind(|p| p.code == code)
            && (p.f64()? - want).abs() > 1e-12
        {
            return Err(p.error(format!(
                "{} has an extrusion direction other than +z (object coordinates are not \
                 supported)",
                head.value
            )));
        }
    }
    Ok(())
}

/// Refuses arc segments (group code 42 bulge ≠ 0).
fn no_bulge(head: &Pair<'_>, body: &[Pair<'_>]) -> Result<(), Error> {
    for p in body.iter().filter(|p| p.code == 42) {
        if p.f64()? != 0.0 {
            return Err(p.error(format!(
                "{} has an arc segment (bulge {}); only straight segments are supported",
                head.value, p.value
            )));
        }
    }
    Ok(())
}

fn lwpolyline(head: &Pair<'_>, body: &[Pair<'_>]) -> Result<Entity, Error> {
    world_extrusion(head, body)?;
    no_bulge(head, body)?;
    let elevation_pair = body.iter().rfind(|p| p.code == 38);
    let elevation = elevation_pair.map_or(Ok(0.0), Pair::f64)?;
    let elevation_place = elevation_pair.map_or(head.place(), Pair::place);
    let mut points: Vec<[f64; 3]> = Vec::new();
    let mut places: Vec<[Place; 3]> = Vec::new();
    let mut pending_x: Option<&Pair<'_>> = None;
    for p in body {
        match p.code {
            10 => {
                if let Some(x) = pending_x {
                    return Err(x.error("vertex x (group code 10) without a y (group code 20)"));
                }
                pending_x = Some(p);
            }
            20 => {
                let Some(x) = pending_x.take() else {
                    return Err(p.error("vertex y (group code 20) without an x (group code 10)"));
                };
                points.push([x.f64()?, p.f64()?, elevation]);
                places.push([x.place(), p.place(), elevation_place]);
            }
            _ => {}
        }
    }
    if let Some(x) = pending_x {
        return Err(x.error("vertex x (group code 10) without a y (group code 20)"));
    }
    if let Some(count) = body.iter().find(|p| p.code == 90) {
        let declared = count.int()?;
        if usize::try_from(declared).ok() != Some(points.len()) {
            return Err(count.error(format!(
                "LWPOLYLINE declares {declared} vertices but has {}",
                points.len()
            )));
        }
    }
    Ok(Entity {
        kind: Kind::LwPolyline,
        layer: layer(body),
        points,
        closed: flags(body)? & 1 != 0,
        places,
    })
}

/// A POLYLINE and its VERTEX entities up to SEQEND; returns the entity (none for meshes) and the
/// index after SEQEND's body.
fn polyline(
    head: &Pair<'_>,
    body: &[Pair<'_>],
    pairs: &[Pair<'_>],
    mut i: usize,
) -> Result<(Option<Entity>, usize), Error> {
    let polyline_flags = flags(body)?;
    let is_3d = polyline_flags & 8 != 0;
    // 16 = 3D polygon mesh, 64 = polyface mesh: surfaces, not paths.
    let is_mesh = polyline_flags & (16 | 64) != 0;
    if !is_3d && !is_mesh {
        world_extrusion(head, body)?;
    }
    let elevation_pair = body.iter().rfind(|p| p.code == 30);
    let elevation = elevation_pair.map_or(Ok(0.0), Pair::f64)?;
    let elevation_place = elevation_pair.map_or(head.place(), Pair::place);
    let mut points = Vec::new();
    let mut places = Vec::new();
    loop {
        let Some(vertex) = pairs.get(i) else {
            return Err(head.error(format!(
                "POLYLINE at line {} has no SEQEND (the file is truncated)",
                head.code_line
            )));
        };
        let end = next_entity(pairs, i + 1);
        let vbody = &pairs[i + 1..end];
        i = end;
        match vertex.value {
            "SEQEND" => break,
            "VERTEX" => {
                if is_mesh {
                    continue;
                }
                // 16 = spline frame control point: not on the fitted curve.
                if flags(vbody)? & 16 != 0 {
                    continue;
                }
                no_bulge(vertex, vbody)?;
                let (mut p, mut place) = xyz(vertex, vbody, 10)?;
                if !is_3d {
                    p[2] = elevation;
                    place[2] = elevation_place;
                }
                points.push(p);
                places.push(place);
            }
            other => {
                return Err(vertex.error(format!(
                    "POLYLINE at line {} expects VERTEX or SEQEND, found `{other}`",
                    head.code_line
                )));
            }
        }
    }
    let entity = (!is_mesh).then(|| Entity {
        kind: Kind::Polyline,
        layer: layer(body),
        points,
        closed: polyline_flags & 1 != 0,
        places,
    });
    Ok((entity, i))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Pairs given as (code, value) written one per line, LF endings.
    fn dxf(pairs: &[(i32, &str)]) -> String {
        pairs.iter().map(|(c, v)| format!("{c}\n{v}\n")).collect()
    }

    const PATH_POINTS: &str = "  0\nSECTION\n  2\nHEADER\n  9\n$ACADVER\n  1\nAC1009\n  0\nENDSEC\n\
  0\nSECTION\n  2\nENTITIES\n\
  0\nPOINT\n  8\nPATH\n 10\n1.5\n 20\n-2.0\n 30\n100.25\n\
  0\nCIRCLE\n  8\nMANDREL\n 10\n0\n 20\n0\n 30\n0\n 40\n50\n\
  0\nPOINT\n  8\nPATH\n 10\n3.0\n 20\n-1.0\n 30\n110\n\
  0\nENDSEC\n  0\nEOF\n";

    #[test]
    fn points_in_file_order_and_unknown_entities_skipped() {
        let d = Drawing::parse(PATH_POINTS).unwrap();
        assert_eq!(d.entities.len(), 2);
        assert_eq!(d.entities[0].kind, Kind::Point);
        assert_eq!(d.entities[0].layer, "PATH");
        assert_eq!(d.entities[0].points, vec![[1.5, -2.0, 100.25]]);
        assert_eq!(
            d.path(None).unwrap(),
            vec![[1.5, -2.0, 100.25], [3.0, -1.0, 110.0]]
        );
        assert!(d.path(Some("MANDREL")).is_err());
    }

    #[test]
    fn crlf_and_odd_whitespace_parse_the_same() {
        let crlf = PATH_POINTS.replace('\n', "\r\n");
        assert_eq!(
            Drawing::parse(&crlf).unwrap(),
            Drawing::parse(PATH_POINTS).unwrap()
        );
        let spaced = PATH_POINTS
            .replace("\n 10\n1.5\n", "\n10   \n   1.5  \n")
            .replace("\n  8\nPATH\n", "\n8\n  PATH \t\n");
        assert_eq!(
            Drawing::parse(&spaced).unwrap(),
            Drawing::parse(PATH_POINTS).unwrap()
        );
    }

    #[test]
    fn polyline_with_vertices_and_seqend() {
        let text = dxf(&[
            (0, "SECTION"),
            (2, "ENTITIES"),
            (0, "POLYLINE"),
            (8, "FIBRE"),
            (66, "1"),
            (10, "0"),
            (20, "0"),
            (30, "0"),
            (70, "8"),
            (0, "VERTEX"),
            (10, "1"),
            (20, "2"),
            (30, "3"),
            (70, "32"),
            (0, "VERTEX"),
            (10, "4"),
            (20, "5"),
            (30, "6"),
            (70, "32"),
            (0, "SEQEND"),
            (0, "LINE"),
            (10, "0"),
            (20, "0"),
            (11, "1"),
            (21, "1"),
            (31, "1"),
            (0, "ENDSEC"),
            (0, "EOF"),
        ]);
        let d = Drawing::parse(&text).unwrap();
        assert_eq!(d.entities.len(), 2);
        assert_eq!(d.entities[0].kind, Kind::Polyline);
        assert_eq!(d.entities[0].layer, "FIBRE");
        assert_eq!(d.entities[0].points, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert_eq!(d.entities[1].layer, "0");
        assert_eq!(d.entities[1].points, vec![[0.0; 3], [1.0, 1.0, 1.0]]);
        // A path is the one polyline, whatever else is there.
        assert_eq!(d.path(None).unwrap().len(), 2);
    }

    #[test]
    fn two_d_polyline_takes_its_elevation_and_skips_spline_frame_points() {
        let text = dxf(&[
            (0, "SECTION"),
            (2, "ENTITIES"),
            (0, "POLYLINE"),
            (66, "1"),
            (10, "0"),
            (20, "0"),
            (30, "7.5"),
            (70, "4"),
            (0, "VERTEX"),
            (10, "9"),
            (20, "9"),
            (70, "16"),
            (0, "VERTEX"),
            (10, "1"),
            (20, "2"),
            (70, "8"),
            (0, "VERTEX"),
            (10, "3"),
            (20, "4"),
            (70, "8"),
            (0, "SEQEND"),
            (0, "ENDSEC"),
            (0, "EOF"),
        ]);
        let d = Drawing::parse(&text).unwrap();
        assert_eq!(d.entities[0].points, vec![[1.0, 2.0, 7.5], [3.0, 4.0, 7.5]]);
    }

    #[test]
    fn lwpolyline_profile() {
        let text = dxf(&[
            (0, "SECTION"),
            (2, "ENTITIES"),
            (0, "LWPOLYLINE"),
            (8, "SPINE"),
            (90, "3"),
            (70, "0"),
            (10, "0"),
            (20, "0"),
            (10, "10"),
            (20, "0.4"),
            (10, "20"),
            (20, "1.6"),
            (0, "ENDSEC"),
            (0, "EOF"),
        ]);
        let d = Drawing::parse(&text).unwrap();
        assert_eq!(d.entities[0].kind, Kind::LwPolyline);
        assert_eq!(
            d.profile(Some("SPINE")).unwrap(),
            vec![(0.0, 0.0), (10.0, 0.4), (20.0, 1.6)]
        );
        let falling = text.replace("10\n20\n20\n1.6", "10\n5\n20\n1.6");
        let e = Drawing::parse(&falling).unwrap().profile(None).unwrap_err();
        assert!(e.to_string().contains("does not rise"), "{e}");
    }

    #[test]
    fn lines_chain_into_a_path() {
        let mut d = Drawing::default();
        for k in 0..3 {
            d.entities.push(Entity {
                kind: Kind::Line,
                layer: "0".into(),
                points: vec![[k as f64, 0.0, 0.0], [k as f64 + 1.0, 0.0, 0.0]],
                closed: false,
                places: Vec::new(),
            });
        }
        assert_eq!(d.path(None).unwrap().len(), 4);
        d.entities[2].points[0][1] = 0.5;
        assert!(d.path(None).unwrap_err().to_string().contains("0.500 mm"));
    }

    #[test]
    fn errors_name_line_and_column() {
        // Truncated in the middle of the ENTITIES section: the second POINT's code 30 (line 45)
        // has no value line.
        let truncated = &PATH_POINTS[..PATH_POINTS.find("110").unwrap() - 1];
        let e = Drawing::parse(truncated).unwrap_err();
        assert!(e.to_string().starts_with("46:1:"), "{e}");
        assert!(e.to_string().contains("truncated"), "{e}");
        // Truncated on a pair boundary, before ENDSEC.
        let cut = &PATH_POINTS[..PATH_POINTS.find("0\nENDSEC\n  0\nEOF").unwrap()];
        let e = Drawing::parse(cut).unwrap_err();
        assert!(e.to_string().contains("truncated"), "{e}");
        // A bad number: line 22 (value of code 20 of the first POINT), column 2.
        let bad = PATH_POINTS.replacen("\n-2.0\n", "\n -2,0\n", 1);
        let e = Drawing::parse(&bad).unwrap_err();
        assert_eq!(
            e.in_file("path.dxf").to_string(),
            "path.dxf:22:2: group code 20 expects a number, found `-2,0`"
        );
        // A bad group code.
        let e = Drawing::parse("  0\nSECTION\nxx\nENTITIES\n").unwrap_err();
        assert!(
            e.to_string().starts_with("3:1: expected a group code"),
            "{e}"
        );
        // A POINT without y.
        let e = Drawing::parse(&dxf(&[
            (0, "SECTION"),
            (2, "ENTITIES"),
            (0, "POINT"),
            (10, "1"),
            (0, "ENDSEC"),
            (0, "EOF"),
        ]))
        .unwrap_err();
        assert!(e.to_string().starts_with("6:1:"), "{e}");
        assert!(e.to_string().contains("group code 20"), "{e}");
    }

    #[test]
    fn arcs_and_object_coordinates_are_refused() {
        let bulge = dxf(&[
            (0, "SECTION"),
            (2, "ENTITIES"),
            (0, "LWPOLYLINE"),
            (10, "0"),
            (20, "0"),
            (42, "0.5"),
            (10, "1"),
            (20, "0"),
            (0, "ENDSEC"),
            (0, "EOF"),
        ]);
        let e = Drawing::parse(&bulge).unwrap_err();
        assert!(e.to_string().starts_with("12:1:"), "{e}");
        let ocs = bulge.replace("42\n0.5", "230\n-1");
        assert!(
            Drawing::parse(&ocs)
                .unwrap_err()
                .to_string()
                .contains("extrusion")
        );
    }

    #[test]
    fn missing_seqend_and_wrong_lwpolyline_count() {
        let e = Drawing::parse(&dxf(&[
            (0, "SECTION"),
            (2, "ENTITIES"),
            (0, "POLYLINE"),
            (70, "8"),
            (0, "VERTEX"),
            (10, "1"),
            (20, "2"),
            (0, "ENDSEC"),
            (0, "EOF"),
        ]))
        .unwrap_err();
        assert!(e.to_string().contains("SEQEND"), "{e}");
        let e = Drawing::parse(&dxf(&[
            (0, "SECTION"),
            (2, "ENTITIES"),
            (0, "LWPOLYLINE"),
            (90, "3"),
            (10, "1"),
            (20, "2"),
            (0, "ENDSEC"),
            (0, "EOF"),
        ]))
        .unwrap_err();
        assert!(
            e.to_string().contains("declares 3 vertices but has 1"),
            "{e}"
        );
    }

    #[test]
    fn written_drawings_round_trip() {
        let d = Drawing {
            entities: vec![
                Entity {
                    kind: Kind::Point,
                    layer: "P".into(),
                    points: vec![[0.1, -31.75, 1e-7]],
                    closed: false,
                    places: Vec::new(),
                },
                Entity {
                    kind: Kind::Polyline,
                    layer: "FIBRE 1".into(),
                    points: vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.5]],
                    closed: true,
                    places: Vec::new(),
                },
                Entity {
                    kind: Kind::LwPolyline,
                    layer: "SPINE".into(),
                    points: vec![[0.0, 0.0, 2.0], [10.0, 0.4, 2.0]],
                    closed: false,
                    places: Vec::new(),
                },
                Entity {
                    kind: Kind::Line,
                    layer: "0".into(),
                    points: vec![[0.0; 3], [1.0; 3]],
                    closed: false,
                    places: Vec::new(),
                },
            ],
            units: Some(Units::Metres),
        };
        let text = d.write().unwrap();
        assert_eq!(Drawing::parse(&text).unwrap(), d);
        let mut bad = d.clone();
        bad.entities[2].points[1][2] = 3.0;
        assert!(bad.write().is_err());
        let mut bad = d;
        bad.entities[0].layer = "a\nb".into();
        assert!(bad.write().is_err());
    }

    /// A path of two POINTs in a drawing whose HEADER gives `$INSUNITS` = `code`.
    fn with_units(code: &str) -> String {
        dxf(&[
            (0, "SECTION"),
            (2, "HEADER"),
            (9, "$ACADVER"),
            (1, "AC1015"),
            (9, "$INSUNITS"),
            (70, code),
            (0, "ENDSEC"),
            (0, "SECTION"),
            (2, "ENTITIES"),
            (0, "POINT"),
            (10, "0.0285"),
            (20, "0"),
            (30, "0.35"),
            (0, "POINT"),
            (10, "0"),
            (20, "0.0285"),
            (30, "0.1"),
            (0, "ENDSEC"),
            (0, "EOF"),
        ])
    }

    #[test]
    fn insunits_scales_paths_to_millimetres() {
        let metres = Drawing::parse(&with_units("6")).unwrap();
        assert_eq!(metres.units, Some(Units::Metres));
        let path = metres.path(None).unwrap();
        // 0.0285 m = 28.5 mm, 0.35 m = 350 mm (to rounding of the decimal scale).
        for (got, want) in path[0].iter().zip([28.5, 0.0, 350.0]) {
            assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        }
        let inches = Drawing::parse(&with_units("1"))
            .unwrap()
            .path(None)
            .unwrap();
        assert!((inches[0][0] - 0.0285 * 25.4).abs() < 1e-12);
        for (code, scale) in [("0", 1.0), ("4", 1.0), ("5", 10.0), ("2", 304.8)] {
            let p = Drawing::parse(&with_units(code))
                .unwrap()
                .path(None)
                .unwrap();
            assert!((p[1][2] - 0.1 * scale).abs() < 1e-12, "{code}");
        }
        // Absent: millimetres, as drawn.
        let absent = with_units("4").replace("  9\n$INSUNITS\n 70\n4\n", "");
        let absent = absent.replace("9\n$INSUNITS\n70\n4\n", "");
        let d = Drawing::parse(&absent).unwrap();
        assert_eq!(d.units, None);
        assert_eq!(d.path(None).unwrap()[0], [0.0285, 0.0, 0.35]);
        // A spine profile is scaled the same way.
        let spine = Drawing {
            entities: vec![Entity {
                kind: Kind::LwPolyline,
                layer: "SPINE".into(),
                points: vec![[0.0, 0.0, 0.0], [0.5, 0.25, 0.0]],
                closed: false,
                places: Vec::new(),
            }],
            units: Some(Units::Centimetres),
        };
        assert_eq!(spine.profile(None).unwrap(), vec![(0.0, 0.0), (5.0, 2.5)]);
    }

    #[test]
    fn unknown_units_are_refused_at_their_value() {
        // Line 12 holds the value of code 70 after `9 $INSUNITS`.
        let e = Drawing::parse(&with_units("13")).unwrap_err().to_string();
        assert!(e.starts_with("12:1: $INSUNITS 13 is a unit"), "{e}");
        let e = Drawing::parse(&with_units("m")).unwrap_err().to_string();
        assert!(e.starts_with("12:1:"), "{e}");
        let wrong_code = with_units("6").replace("70\n6\n", "40\n6\n");
        let e = Drawing::parse(&wrong_code).unwrap_err().to_string();
        assert!(e.starts_with("12:1:") && e.contains("group code 70"), "{e}");
    }

    #[test]
    fn path_points_know_where_each_coordinate_was_read() {
        let d = Drawing::parse(PATH_POINTS).unwrap();
        let points = d.path_points(None).unwrap();
        // First POINT: x on line 20, y on 22, z on 24 (values after `0 POINT`, `8 PATH`).
        let places = points[0].places.unwrap();
        assert_eq!(places.map(|p| p.line), [20, 22, 24]);
        assert_eq!(places[0].column, 1);
        // A POINT without z places its z at the entity name.
        let no_z = dxf(&[
            (0, "SECTION"),
            (2, "ENTITIES"),
            (0, "POINT"),
            (10, "1"),
            (20, "2"),
            (0, "POINT"),
            (10, "3"),
            (20, "4"),
            (0, "ENDSEC"),
            (0, "EOF"),
        ]);
        let points = Drawing::parse(&no_z).unwrap().path_points(None).unwrap();
        assert_eq!(points[1].places.unwrap().map(|p| p.line), [14, 16, 12]);
        // An LWPOLYLINE's z is its elevation's place; a closed one repeats its first point.
        let lw = dxf(&[
            (0, "SECTION"),
            (2, "ENTITIES"),
            (0, "LWPOLYLINE"),
            (70, "1"),
            (38, "5"),
            (10, "0"),
            (20, "0"),
            (10, "1"),
            (20, "0"),
            (0, "ENDSEC"),
            (0, "EOF"),
        ]);
        let points = Drawing::parse(&lw).unwrap().path_points(None).unwrap();
        assert_eq!(points.len(), 3);
        assert_eq!(points[1].places.unwrap().map(|p| p.line), [16, 18, 10]);
        assert_eq!(points[2], points[0]);
    }

    #[test]
    fn non_finite_coordinates_are_refused_where_they_stand() {
        for bad in ["NaN", "inf", "-inf", "1e309"] {
            let text = PATH_POINTS.replacen("\n-2.0\n", &format!("\n{bad}\n"), 1);
            let e = Drawing::parse(&text).unwrap_err().to_string();
            assert!(e.starts_with("22:1: group code 20 holds"), "{bad}: {e}");
            assert!(e.contains("not a finite number"), "{e}");
        }
    }

    fn entity() -> impl Strategy<Value = Entity> {
        let coordinate = -1e6f64..1e6;
        let point = [coordinate.clone(), coordinate.clone(), coordinate];
        (
            0..4u8,
            "[A-Z0-9_]{1,8}",
            prop::collection::vec(point, 1..8),
            any::<bool>(),
        )
            .prop_map(|(kind, layer, mut points, closed)| {
                let kind =
                    [Kind::Point, Kind::Line, Kind::Polyline, Kind::LwPolyline][kind as usize];
                match kind {
                    Kind::Point => points.truncate(1),
                    Kind::Line => {
                        let first = points[0];
                        points = vec![first, [first[1], first[2], first[0]]];
                    }
                    Kind::Polyline => {}
                    Kind::LwPolyline => {
                        let z = points[0][2];
                        for p in &mut points {
                            p[2] = z;
                        }
                    }
                }
                let closed = closed && matches!(kind, Kind::Polyline | Kind::LwPolyline);
                Entity {
                    kind,
                    layer,
                    points,
                    closed,
                    places: Vec::new(),
                }
            })
    }

    proptest! {
        #[test]
        fn random_drawings_round_trip(
            entities in prop::collection::vec(entity(), 0..6),
            units in prop::option::of(prop::sample::select(Units::ALL.to_vec())),
        ) {
            let d = Drawing { entities, units };
            let text = d.write().unwrap();
            prop_assert_eq!(Drawing::parse(&text).unwrap(), d.clone());
            prop_assert_eq!(Drawing::parse(&text.replace('\n', "\r\n")).unwrap(), d);
        }

        #[test]
        fn reader_never_panics_on_arbitrary_text(text in "(?s).{0,400}") {
            let _ = Drawing::parse(&text);
        }

        #[test]
        fn reader_never_panics_on_damaged_drawings(
            entities in prop::collection::vec(entity(), 1..4),
            cut in 0usize..2000,
            junk in "[0-9A-Z \\-\\.\r\n]{0,6}",
        ) {
            let text = Drawing { entities, units: None }.write().unwrap();
            let mut cut = cut.min(text.len());
            while !text.is_char_boundary(cut) {
                cut -= 1;
            }
            let damaged = format!("{}{}{}", &text[..cut], junk, &text[cut..]);
            let _ = Drawing::parse(&damaged);
            let _ = Drawing::parse(&text[..cut]).map(|d| d.path(None));
        }
    }
}
