//! Robot programs (RAPID, KRL, FANUC TP, URScript) checked against what does not come from the
//! code under test: poses from a forward kinematics written here from the published equations
//! (the OPW structure of Brandstötter et al. 2014 with ROS-Industrial's published parameters;
//! UR's Denavit–Hartenberg table), numbers read back by minimal readers written here from each
//! vendor's documented syntax, and configuration data checked against rules written from the
//! vendors' manuals (ABB `confdata`, KUKA Status/Turn, FANUC CONFIG). Then the same through
//! windcell's own readers, the errors they give, and mutations of written programs (no panic,
//! bounded time).

use std::collections::HashMap;
use std::f64::consts::PI;

use paths::arm::{SixAxisArm, Tool};
use sequences::Error;
use sequences::program::{
    self, ConfigData, ExternalAxis, Format, Frame, MandrelCoupling, Motion, ProgramPath,
    ProgramTarget, ReadProgram, Step, SyncSignals, WriteOptions, Zone,
};

// ------------------------------------------------------------------------------------------
// Small linear algebra, written here.

type M3 = [[f64; 3]; 3];

fn mul(a: &M3, b: &M3) -> M3 {
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

fn mulv(a: &M3, v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| (0..3).map(|k| a[i][k] * v[k]).sum())
}

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn transpose(a: &M3) -> M3 {
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| a[j][i]))
}

fn rx(t: f64) -> M3 {
    let (s, c) = t.sin_cos();
    [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]
}

fn ry(t: f64) -> M3 {
    let (s, c) = t.sin_cos();
    [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
}

fn rz(t: f64) -> M3 {
    let (s, c) = t.sin_cos();
    [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
}

/// The angle between two rotations, degrees.
fn angle_deg(a: &M3, b: &M3) -> f64 {
    let r = mul(&transpose(a), b);
    let c = ((r[0][0] + r[1][1] + r[2][2] - 1.0) / 2.0).clamp(-1.0, 1.0);
    // acos loses precision near 0: use the skew part as well.
    let s =
        ((r[2][1] - r[1][2]).powi(2) + (r[0][2] - r[2][0]).powi(2) + (r[1][0] - r[0][1]).powi(2))
            .sqrt()
            / 2.0;
    s.atan2(c).to_degrees()
}

/// Unit quaternion `[w, x, y, z]` → matrix (Hamilton convention, as ABB's `orient` uses).
fn quat_matrix(q: [f64; 4]) -> M3 {
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    let [w, x, y, z] = q.map(|v| v / n);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// Matrix → quaternion by the trace (with the other three branches for small traces).
fn matrix_quat(m: &M3) -> [f64; 4] {
    let t = m[0][0] + m[1][1] + m[2][2];
    let q = if t > 0.0 {
        let s = 0.5 / (t + 1.0).sqrt();
        [
            0.25 / s,
            (m[2][1] - m[1][2]) * s,
            (m[0][2] - m[2][0]) * s,
            (m[1][0] - m[0][1]) * s,
        ]
    } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
        let s = 2.0 * (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt();
        [
            (m[2][1] - m[1][2]) / s,
            0.25 * s,
            (m[0][1] + m[1][0]) / s,
            (m[0][2] + m[2][0]) / s,
        ]
    } else if m[1][1] > m[2][2] {
        let s = 2.0 * (1.0 + m[1][1] - m[0][0] - m[2][2]).sqrt();
        [
            (m[0][2] - m[2][0]) / s,
            (m[0][1] + m[1][0]) / s,
            0.25 * s,
            (m[1][2] + m[2][1]) / s,
        ]
    } else {
        let s = 2.0 * (1.0 + m[2][2] - m[0][0] - m[1][1]).sqrt();
        [
            (m[1][0] - m[0][1]) / s,
            (m[0][2] + m[2][0]) / s,
            (m[1][2] + m[2][1]) / s,
            0.25 * s,
        ]
    };
    if q[0] < 0.0 { q.map(|v| -v) } else { q }
}

/// Rodrigues' formula: rotation vector (rad) → matrix.
fn rotvec_matrix(r: [f64; 3]) -> M3 {
    let th = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
    if th < 1e-15 {
        return rx(0.0);
    }
    let k = r.map(|v| v / th);
    let kx: M3 = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
    let k2 = mul(&kx, &kx);
    let (s, c) = th.sin_cos();
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = f64::from(u8::from(i == j)) + s * kx[i][j] + (1.0 - c) * k2[i][j];
        }
    }
    m
}

// ------------------------------------------------------------------------------------------
// Independent forward kinematics.

/// OPW parameters (ROS-Industrial `opw_parameters_*.yaml`, mm), joint offsets and signs.
struct OpwParams {
    a1: f64,
    a2: f64,
    b: f64,
    c1: f64,
    c2: f64,
    c3: f64,
    c4: f64,
    offsets_deg: [f64; 6],
    signs: [f64; 6],
    min_deg: [f64; 6],
    max_deg: [f64; 6],
}

/// ABB IRB 2600-12/1.65 (opw_parameters_irb2600_12_165.yaml; ABB product specification ranges).
const IRB2600: OpwParams = OpwParams {
    a1: 150.0,
    a2: -115.0,
    b: 0.0,
    c1: 445.0,
    c2: 700.0,
    c3: 795.0,
    c4: 85.0,
    offsets_deg: [0.0, 0.0, -90.0, 0.0, 0.0, 0.0],
    signs: [1.0; 6],
    min_deg: [-180.0, -95.0, -180.0, -400.0, -120.0, -400.0],
    max_deg: [180.0, 155.0, 75.0, 400.0, 120.0, 400.0],
};

/// KUKA KR 16-2 (opw_parameters_kr16_2.yaml; KUKA data sheet ranges).
const KR16: OpwParams = OpwParams {
    a1: 260.0,
    a2: 35.0,
    b: 0.0,
    c1: 675.0,
    c2: 680.0,
    c3: 670.0,
    c4: 158.0,
    offsets_deg: [0.0, -90.0, 0.0, 0.0, 0.0, 0.0],
    signs: [-1.0, 1.0, 1.0, -1.0, 1.0, -1.0],
    min_deg: [-185.0, -155.0, -130.0, -350.0, -130.0, -350.0],
    max_deg: [185.0, 35.0, 154.0, 350.0, 130.0, 350.0],
};

/// FANUC M-20iA (opw_parameters_m20ia10l-like yaml for the M-20iA; ROS-Industrial URDF ranges).
const M20IA: OpwParams = OpwParams {
    a1: 150.0,
    a2: -250.0,
    b: 0.0,
    c1: 525.0,
    c2: 790.0,
    c3: 835.0,
    c4: 100.0,
    offsets_deg: [0.0, 0.0, -90.0, 0.0, 0.0, 180.0],
    signs: [1.0, 1.0, -1.0, -1.0, -1.0, -1.0],
    min_deg: [-170.0, -100.0, -185.0, -200.0, -140.0, -270.0],
    max_deg: [170.0, 160.0, 273.0, 200.0, 140.0, 270.0],
};

/// The points of an OPW arm for its joints, built link by link (the paper's Fig. 1 chain:
/// axis 1 about z, the shoulder offset (a1, 0, c1), axis 2 about y, the upper arm c2 up,
/// axis 3 about y, the forearm offset (a2, b, c3) to the wrist centre, then z–y–z wrist axes
/// and the flange c4 along the last z).
struct OpwPose {
    flange_r: M3,
    flange_t: [f64; 3],
    /// Axis 2 and 3 points and the wrist centre.
    axis2: [f64; 3],
    axis3: [f64; 3],
    wrist: [f64; 3],
    /// Model angle of axis 1, rad.
    q1: f64,
}

fn opw_fk(p: &OpwParams, joints_deg: &[f64; 6]) -> OpwPose {
    let q: Vec<f64> = (0..6)
        .map(|i| (p.signs[i] * joints_deg[i] - p.offsets_deg[i]).to_radians())
        .collect();
    let r1 = rz(q[0]);
    let axis2 = mulv(&r1, [p.a1, 0.0, p.c1]);
    let r2 = mul(&r1, &ry(q[1]));
    let axis3 = add(axis2, mulv(&r2, [0.0, 0.0, p.c2]));
    let r3 = mul(&r2, &ry(q[2]));
    let wrist = add(axis3, mulv(&r3, [p.a2, p.b, p.c3]));
    let r6 = mul(&mul(&mul(&r3, &rz(q[3])), &ry(q[4])), &rz(q[5]));
    OpwPose {
        flange_t: add(wrist, mulv(&r6, [0.0, 0.0, p.c4])),
        flange_r: r6,
        axis2,
        axis3,
        wrist,
        q1: q[0],
    }
}

/// UR10e's DH table (Universal Robots, "DH parameters for calculations of kinematics and
/// dynamics"), metres there, mm here.
const UR10E_D: [f64; 6] = [180.7, 0.0, 0.0, 174.15, 119.85, 116.55];
const UR10E_A: [f64; 6] = [0.0, -612.7, -571.55, 0.0, 0.0, 0.0];
const UR_ALPHA: [f64; 6] = [PI / 2.0, 0.0, 0.0, PI / 2.0, -PI / 2.0, 0.0];

fn ur_fk(joints_deg: &[f64; 6]) -> (M3, [f64; 3]) {
    let mut r = rx(0.0);
    let mut t = [0.0; 3];
    for i in 0..6 {
        let th = joints_deg[i].to_radians();
        // T_i = Rz(θ) Tz(d) Tx(a) Rx(α)
        t = add(t, mulv(&r, [0.0, 0.0, UR10E_D[i]]));
        r = mul(&r, &rz(th));
        t = add(t, mulv(&r, [UR10E_A[i], 0.0, 0.0]));
        r = mul(&r, &rx(UR_ALPHA[i]));
    }
    (r, t)
}

// ------------------------------------------------------------------------------------------
// Test programs.

struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

/// The eye on the flange: 20 mm off axis, 180 mm out, tilted 25° about the flange's y.
const TCP_MM: [f64; 3] = [20.0, 0.0, 180.0];
const TOOL_PITCH_DEG: f64 = 25.0;

fn tool_frame() -> Frame {
    Frame {
        position_mm: TCP_MM,
        orientation: matrix_quat(&ry(TOOL_PITCH_DEG.to_radians())),
    }
}

fn arm_tool() -> Tool {
    Tool {
        tcp_mm: TCP_MM,
        rpy_deg: [0.0, TOOL_PITCH_DEG, 0.0],
    }
}

/// The work frame of the coupled tests: 1200 mm ahead, 300 mm up, turned 30° about z.
fn coupled_work() -> (M3, [f64; 3]) {
    (rz(30f64.to_radians()), [1200.0, 0.0, 300.0])
}

enum Kin<'a> {
    Opw(&'a OpwParams),
    Ur,
}

/// A path of `n` random reachable targets, from joints inside the ranges less 5°.
fn random_path(kin: &Kin<'_>, n: usize, seed: u64, coupled: bool) -> ProgramPath {
    let mut rng = Rng(seed);
    let (tool_r, tool_t) = (ry(TOOL_PITCH_DEG.to_radians()), TCP_MM);
    let (work_r, work_t) = if coupled {
        coupled_work()
    } else {
        (rx(0.0), [0.0; 3])
    };
    let mut targets = Vec::new();
    for i in 0..n {
        let joints_deg: [f64; 6] = std::array::from_fn(|k| match kin {
            Kin::Opw(p) => rng.range(p.min_deg[k] + 5.0, p.max_deg[k] - 5.0),
            Kin::Ur => rng.range(-355.0, 355.0),
        });
        let (fr, ft) = match kin {
            Kin::Opw(p) => {
                let f = opw_fk(p, &joints_deg);
                (f.flange_r, f.flange_t)
            }
            Kin::Ur => ur_fk(&joints_deg),
        };
        // Tool in base, then in the work frame.
        let tr = mul(&fr, &tool_r);
        let tt = add(ft, mulv(&fr, tool_t));
        let wr = mul(&transpose(&work_r), &tr);
        let wt = mulv(&transpose(&work_r), sub(tt, work_t));
        let mut q = matrix_quat(&wr);
        if i % 5 == 3 {
            // A quaternion given with w < 0 is the same rotation.
            q = q.map(|v| -v);
        }
        targets.push(ProgramTarget {
            position_mm: wt,
            orientation: q,
            joints_deg,
            external_deg: coupled.then(|| rng.range(-720.0, 720.0)),
            duration_s: if i == 0 { 0.0 } else { rng.range(0.05, 3.0) },
            speed_mm_s: if i == 0 { 0.0 } else { rng.range(20.0, 900.0) },
            zone_mm: if i % 4 == 1 { 0.0 } else { rng.range(0.5, 8.0) },
            sync: !coupled && i > 0 && i % 3 == 0,
        });
    }
    ProgramPath {
        name: "sbend 1".into(),
        tool: tool_frame(),
        work: if coupled {
            Frame {
                position_mm: work_t,
                orientation: matrix_quat(&work_r),
            }
        } else {
            Frame::IDENTITY
        },
        mandrel: if coupled {
            MandrelCoupling::Coupled {
                axis: ExternalAxis {
                    number: 1,
                    mechanical_unit: "STN1".into(),
                },
            }
        } else {
            MandrelCoupling::Decoupled {
                sync: SyncSignals {
                    start_output: 5,
                    in_position_input: 7,
                },
            }
        },
        targets,
    }
}

fn arm(model: &str) -> SixAxisArm {
    if model.starts_with("ur") {
        SixAxisArm::ur_preset(model, arm_tool()).unwrap()
    } else {
        SixAxisArm::opw_preset(model, arm_tool()).unwrap()
    }
}

// ------------------------------------------------------------------------------------------
// What a program must do, as events.

#[derive(Debug, Clone, PartialEq)]
enum Ev {
    Move {
        joint: bool,
        position_mm: [f64; 3],
        rotation: M3,
        /// Configuration as text (format-specific).
        config: String,
        external_deg: Option<f64>,
        /// mm/s (None for a joint move).
        speed: Option<f64>,
        time: Option<f64>,
        /// Zone, mm (0: stop point).
        zone: f64,
    },
    Out(u16, bool),
    Wait(u16, bool),
}

/// The documented sync protocol around each target.
fn expected_events(path: &ProgramPath) -> Vec<Ev> {
    let sync = match path.mandrel {
        MandrelCoupling::Decoupled { sync } => Some(sync),
        MandrelCoupling::Coupled { .. } => None,
    };
    let mut out = Vec::new();
    for (i, t) in path.targets.iter().enumerate() {
        let mv = Ev::Move {
            joint: i == 0,
            position_mm: t.position_mm,
            rotation: quat_matrix(t.orientation),
            config: String::new(),
            external_deg: t.external_deg,
            speed: (i > 0).then_some(t.speed_mm_s),
            time: (i > 0).then_some(t.duration_s),
            zone: if t.sync && sync.is_some() {
                0.0
            } else {
                t.zone_mm
            },
        };
        match (t.sync, sync) {
            (true, Some(s)) if i > 0 => {
                out.push(Ev::Out(s.start_output, true));
                out.push(mv);
                out.push(Ev::Wait(s.in_position_input, true));
                out.push(Ev::Out(s.start_output, false));
                out.push(Ev::Wait(s.in_position_input, false));
            }
            _ => out.push(mv),
        }
    }
    out
}

/// Tolerances of a format's printed numbers.
struct Tol {
    position_mm: f64,
    angle_deg: f64,
    speed_mm_s: f64,
    time_s: Option<f64>,
    zone_mm: f64,
}

fn compare(format: &str, got: &[Ev], want: &[Ev], tol: &Tol) {
    assert_eq!(
        got.len(),
        want.len(),
        "{format}: {} events, expected {}",
        got.len(),
        want.len()
    );
    let (mut worst_mm, mut worst_deg) = (0.0f64, 0.0f64);
    for (k, (g, w)) in got.iter().zip(want).enumerate() {
        match (g, w) {
            (
                Ev::Move {
                    joint,
                    position_mm,
                    rotation,
                    external_deg,
                    speed,
                    time,
                    zone,
                    ..
                },
                Ev::Move {
                    joint: wj,
                    position_mm: wp,
                    rotation: wr,
                    external_deg: we,
                    speed: ws,
                    time: wt,
                    zone: wz,
                    ..
                },
            ) => {
                assert_eq!(joint, wj, "{format} event {k}: motion type");
                let d = sub(*position_mm, *wp);
                let dist = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                worst_mm = worst_mm.max(dist);
                worst_deg = worst_deg.max(angle_deg(rotation, wr));
                match (external_deg, we) {
                    (Some(a), Some(b)) => {
                        assert!((a - b).abs() < 0.01, "{format} {k}: E1 {a} vs {b}")
                    }
                    (None, None) => {}
                    (a, b) => panic!("{format} {k}: external {a:?} vs {b:?}"),
                }
                if !joint {
                    let (s, ws) = (speed.unwrap(), ws.unwrap());
                    assert!(
                        (s - ws).abs() <= tol.speed_mm_s,
                        "{format} {k}: speed {s} vs {ws}"
                    );
                    if let Some(tt) = tol.time_s {
                        let (t, wt) = (time.unwrap(), wt.unwrap());
                        assert!((t - wt).abs() <= tt, "{format} {k}: time {t} vs {wt}");
                    }
                    assert!(
                        (zone - wz).abs() <= tol.zone_mm,
                        "{format} {k}: zone {zone} vs {wz}"
                    );
                }
            }
            _ => assert_eq!(g, w, "{format} event {k}"),
        }
    }
    assert!(
        worst_mm <= tol.position_mm,
        "{format}: worst position error {worst_mm} mm"
    );
    assert!(
        worst_deg <= tol.angle_deg,
        "{format}: worst orientation error {worst_deg}°"
    );
}

// ------------------------------------------------------------------------------------------
// Minimal readers written from the vendors' documented syntax.

fn numbers(s: &str) -> Vec<f64> {
    s.split(|c: char| c == ',' || c == '[' || c == ']' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(|t| t.parse::<f64>().unwrap_or_else(|_| panic!("number `{t}`")))
        .collect()
}

fn files_map(files: &[(String, String)]) -> HashMap<String, String> {
    files.iter().cloned().collect()
}

/// RAPID: `robtarget` and `speeddata`/`zonedata` declarations, `MoveL`/`MoveJ`, `SetDO`,
/// `WaitDI`, and `%"proc"%` late-binding calls (RAPID technical reference).
fn rapid_events(files: &HashMap<String, String>, module: &str, out: &mut Vec<Ev>) {
    let text = &files[&format!("{module}.mod")];
    let mut decl: HashMap<String, String> = HashMap::new();
    for line in text.lines() {
        let l = line.trim();
        if let Some((left, right)) = l.split_once(":=")
            && (left.contains("robtarget")
                || left.contains("speeddata")
                || left.contains("zonedata"))
        {
            let name = left.split_whitespace().last().unwrap().to_string();
            decl.insert(name, right.trim().trim_end_matches(';').to_string());
        }
    }
    for line in text.lines() {
        let l = line.trim();
        if let Some(rest) = l.strip_prefix("%\"") {
            rapid_events(files, rest.split('"').next().unwrap(), out);
        } else if l.starts_with("MoveL ") || l.starts_with("MoveJ ") {
            let args: Vec<&str> = l[6..]
                .trim_end_matches(';')
                .split(',')
                .map(str::trim)
                .collect();
            let v = numbers(&decl[args[0]]);
            assert_eq!(v.len(), 17, "{l}");
            let (speed_name, time) = match args[1].split_once("\\T:=") {
                Some((s, t)) => (s.trim(), Some(t.trim().parse::<f64>().unwrap())),
                None => (args[1], None),
            };
            let speed = if l.starts_with("MoveJ") {
                None
            } else {
                Some(numbers(&decl[speed_name])[0])
            };
            let zone = if args[2] == "fine" {
                0.0
            } else {
                numbers(&decl[args[2]].replace("FALSE", ""))[0]
            };
            out.push(Ev::Move {
                joint: l.starts_with("MoveJ"),
                position_mm: [v[0], v[1], v[2]],
                rotation: quat_matrix([v[3], v[4], v[5], v[6]]),
                config: format!("{},{},{},{}", v[7], v[8], v[9], v[10]),
                external_deg: (v[11] < 8e9).then_some(v[11]),
                speed,
                time,
                zone,
            });
        } else if let Some(rest) = l.strip_prefix("SetDO doWc") {
            let (n, v) = rest.trim_end_matches(';').split_once(',').unwrap();
            out.push(Ev::Out(n.parse().unwrap(), v.trim() == "1"));
        } else if let Some(rest) = l.strip_prefix("WaitDI diWc") {
            let (n, v) = rest.trim_end_matches(';').split_once(',').unwrap();
            out.push(Ev::Wait(n.parse().unwrap(), v.trim() == "1"));
        }
    }
}

/// KRL: `E6POS` aggregates `{X …,Y …,…}` in the `.dat`, `PTP`/`LIN` with `C_DIS`,
/// `$VEL.CP` (m/s), `$APO.CDIS` (mm), `$OUT[n]=`, `WAIT FOR $IN[n]` and calls `NAME()`.
fn krl_events(files: &HashMap<String, String>, module: &str, out: &mut Vec<Ev>) {
    let src = &files[&format!("{module}.src")];
    let mut points: HashMap<String, HashMap<String, f64>> = HashMap::new();
    if let Some(dat) = files.get(&format!("{module}.dat")) {
        for line in dat.lines() {
            if let Some(rest) = line.trim().strip_prefix("DECL E6POS ") {
                let (name, agg) = rest.split_once('=').unwrap();
                let fields = agg
                    .trim_matches(|c| c == '{' || c == '}')
                    .split(',')
                    .map(|kv| {
                        let (k, v) = kv.trim().split_once(' ').unwrap();
                        (k.to_string(), v.parse::<f64>().unwrap())
                    })
                    .collect();
                points.insert(name.to_string(), fields);
            }
        }
    }
    let (mut vel, mut cdis) = (None, 0.0);
    for line in src.lines() {
        let l = line.trim();
        if let Some(v) = l.strip_prefix("$VEL.CP=") {
            vel = Some(v.parse::<f64>().unwrap() * 1000.0);
        } else if let Some(v) = l.strip_prefix("$APO.CDIS=") {
            cdis = v.parse::<f64>().unwrap();
        } else if l.starts_with("LIN ") || l.starts_with("PTP ") {
            let mut words = l.split_whitespace();
            let kind = words.next().unwrap();
            let p = &points[words.next().unwrap()];
            let approx = words.next() == Some("C_DIS");
            // Z-Y'-X'' Euler angles: R = Rz(A)·Ry(B)·Rx(C) (KUKA "Orientation" of a FRAME).
            let r = mul(
                &mul(&rz(p["A"].to_radians()), &ry(p["B"].to_radians())),
                &rx(p["C"].to_radians()),
            );
            out.push(Ev::Move {
                joint: kind == "PTP",
                position_mm: [p["X"], p["Y"], p["Z"]],
                rotation: r,
                config: format!("{},{}", p["S"], p["T"]),
                external_deg: p.get("E1").copied(),
                speed: if kind == "PTP" { None } else { vel },
                time: None,
                zone: if approx { cdis } else { 0.0 },
            });
        } else if let Some(rest) = l.strip_prefix("$OUT[") {
            let (n, v) = rest.split_once("]=").unwrap();
            out.push(Ev::Out(n.parse().unwrap(), v == "TRUE"));
        } else if let Some(rest) = l.strip_prefix("WAIT FOR NOT $IN[") {
            out.push(Ev::Wait(rest.trim_end_matches(']').parse().unwrap(), false));
        } else if let Some(rest) = l.strip_prefix("WAIT FOR $IN[") {
            out.push(Ev::Wait(rest.trim_end_matches(']').parse().unwrap(), true));
        } else if let Some(name) = l.strip_suffix("()")
            && !l.starts_with("DEF")
        {
            krl_events(files, name, out);
        }
    }
}

/// FANUC TP: `/MN` lines `n:L P[i] Vmm/sec CNTk|FINE ;`, `DO[n]=ON ;`, `WAIT DI[n]=ON ;`,
/// `CALL NAME ;`; `/POS` blocks with `CONFIG : '…'`, `X = … mm`, `W = … deg`, `E1 = … deg`.
fn fanuc_events(files: &HashMap<String, String>, program: &str, out: &mut Vec<Ev>) {
    let text = &files[&format!("{program}.ls")];
    let (mn, pos) = text.split_once("/POS").unwrap();
    let mut points: HashMap<u32, (HashMap<String, f64>, String)> = HashMap::new();
    for block in pos.split("P[").skip(1) {
        let (n, rest) = block.split_once(']').unwrap();
        let config = rest.split('\'').nth(1).unwrap().to_string();
        let mut fields = HashMap::new();
        for part in rest.split([',', '\n', '\t']) {
            if let Some((k, v)) = part.split_once('=') {
                let v = v
                    .trim()
                    .trim_end_matches("mm")
                    .trim_end_matches("deg")
                    .trim();
                fields.insert(k.trim().to_string(), v.parse::<f64>().unwrap());
            }
        }
        points.insert(n.parse().unwrap(), (fields, config));
    }
    for line in mn.lines() {
        let Some((_, instr)) = line.split_once(':') else {
            continue;
        };
        let l = instr.trim().trim_end_matches(';').trim();
        if l.starts_with("L P[") || l.starts_with("J P[") {
            let n: u32 = l[4..].split(']').next().unwrap().parse().unwrap();
            let words: Vec<&str> = l.split_whitespace().collect();
            let (f, config) = &points[&n];
            // W, P, R: rotations about the fixed x, y, z axes: R = Rz(R)·Ry(P)·Rx(W).
            let r = mul(
                &mul(&rz(f["R"].to_radians()), &ry(f["P"].to_radians())),
                &rx(f["W"].to_radians()),
            );
            out.push(Ev::Move {
                joint: l.starts_with('J'),
                position_mm: [f["X"], f["Y"], f["Z"]],
                rotation: r,
                config: config.clone(),
                external_deg: f.get("E1").copied(),
                speed: l
                    .starts_with('L')
                    .then(|| words[2].trim_end_matches("mm/sec").parse().unwrap()),
                time: None,
                zone: match words[3] {
                    "FINE" => 0.0,
                    c => c.trim_start_matches("CNT").parse().unwrap(),
                },
            });
        } else if let Some(rest) = l.strip_prefix("DO[") {
            let (n, v) = rest.split_once("]=").unwrap();
            out.push(Ev::Out(n.parse().unwrap(), v == "ON"));
        } else if let Some(rest) = l.strip_prefix("WAIT DI[") {
            let (n, v) = rest.split_once("]=").unwrap();
            out.push(Ev::Wait(n.parse().unwrap(), v == "ON"));
        } else if let Some(name) = l.strip_prefix("CALL ") {
            fanuc_events(files, name.trim(), out);
        }
    }
}

/// URScript: `movej`/`movel(pose_trans(wc_work, p[x,y,z,rx,ry,rz]), a=, v=, t=, r=)`,
/// `set_standard_digital_out(n, b)`, `while [not] get_standard_digital_in(n):`.
fn ur_events(text: &str, out: &mut Vec<Ev>) {
    for line in text.lines() {
        let l = line.trim();
        if l.starts_with("movel(") || l.starts_with("movej(") {
            let inside = l.split("p[").nth(1).unwrap();
            let (pose, args) = inside.split_once(']').unwrap();
            let v = numbers(pose);
            let named: HashMap<&str, f64> = args
                .split(',')
                .filter_map(|a| a.trim().trim_end_matches(')').split_once('='))
                .map(|(k, v)| (k.trim(), v.trim().parse().unwrap()))
                .collect();
            let joint = l.starts_with("movej");
            out.push(Ev::Move {
                joint,
                position_mm: [v[0] * 1000.0, v[1] * 1000.0, v[2] * 1000.0],
                rotation: rotvec_matrix([v[3], v[4], v[5]]),
                config: String::new(),
                external_deg: None,
                speed: (!joint).then(|| named["v"] * 1000.0),
                time: named.get("t").copied(),
                zone: named.get("r").map_or(0.0, |r| r * 1000.0),
            });
            let angle = (v[3] * v[3] + v[4] * v[4] + v[5] * v[5]).sqrt();
            assert!(
                angle <= PI + 1e-6,
                "rotation vector angle {angle} outside [0, π]"
            );
        } else if let Some(rest) = l.strip_prefix("set_standard_digital_out(") {
            let (n, b) = rest.trim_end_matches(')').split_once(',').unwrap();
            out.push(Ev::Out(n.trim().parse().unwrap(), b.trim() == "True"));
        } else if let Some(rest) = l.strip_prefix("while not get_standard_digital_in(") {
            out.push(Ev::Wait(
                rest.split(')').next().unwrap().parse().unwrap(),
                true,
            ));
        } else if let Some(rest) = l.strip_prefix("while get_standard_digital_in(") {
            out.push(Ev::Wait(
                rest.split(')').next().unwrap().parse().unwrap(),
                false,
            ));
        }
    }
}

// ------------------------------------------------------------------------------------------
// Configuration rules from the vendors' manuals.

fn floor_quadrant(deg: f64) -> i64 {
    (deg / 90.0).floor() as i64
}

/// Whether the wrist centre lies in front of axis 1 (in the arm's own vertical plane) and in
/// front of the lower arm (the line axis 2 → axis 3, forward being the side the forearm points
/// to in the upright zero pose).
fn sides(p: &OpwParams, joints_deg: &[f64; 6]) -> (bool, bool) {
    let f = opw_fk(p, joints_deg);
    let dir = [f.q1.cos(), f.q1.sin()];
    let plane = |v: [f64; 3]| (v[0] * dir[0] + v[1] * dir[1], v[2]);
    let front_of_axis1 = plane(f.wrist).0 >= 0.0;
    let u = plane(sub(f.axis3, f.axis2));
    let w = plane(sub(f.wrist, f.axis3));
    let front_of_lower_arm = u.1 * w.0 - u.0 * w.1 >= 0.0;
    (front_of_axis1, front_of_lower_arm)
}

/// ABB confdata (RAPID reference, `confdata`): cf1/cf4/cf6 the quadrant, cfx 0–7 from the
/// wrist centre relative to axis 1 and to the lower arm and the sign of axis 5.
fn abb_rule(joints_deg: &[f64; 6]) -> String {
    let (front1, front_lower) = sides(&IRB2600, joints_deg);
    let cfx = 4 * i64::from(!front1) + 2 * i64::from(!front_lower) + i64::from(joints_deg[4] < 0.0);
    format!(
        "{},{},{},{}",
        floor_quadrant(joints_deg[0]),
        floor_quadrant(joints_deg[3]),
        floor_quadrant(joints_deg[5]),
        cfx
    )
}

/// KUKA Status and Turn (KSS 8 manual): S bit 0 wrist root point in −X of the A1 system, bit 1
/// A3 ≥ φ, bit 2 A5 ≤ 0; T bit i axis i+1 < 0.
fn kuka_rule(joints_deg: &[f64; 6]) -> String {
    let (front1, _) = sides(&KR16, joints_deg);
    // φ: the A3 angle with the wrist root point on the line A2–A3 extended: the forearm's
    // (a2, c3) turned by A3 parallel to the upper arm.
    let phi = -KR16.a2.atan2(KR16.c3).to_degrees();
    let a3 = joints_deg[2];
    let s = i64::from(!front1)
        + 2 * i64::from(a3 >= phi && a3 < phi + 180.0)
        + 4 * i64::from(joints_deg[4] <= 0.0);
    let t: i64 = (0..6).map(|i| i64::from(joints_deg[i] < 0.0) << i).sum();
    format!("{s},{t}")
}

/// FANUC CONFIG (HandlingTool manual): N/F the wrist (F when J5 > 0 in the controller's
/// convention: the flange turned past the forearm's axis), U/D the forearm relative to the
/// lower arm, T/B the wrist centre relative to J1; turn numbers of J1, J4, J6 with
/// J − 360°·t in [−180°, 180°).
fn fanuc_rule(joints_deg: &[f64; 6]) -> String {
    let (front1, front_lower) = sides(&M20IA, joints_deg);
    let turn = |j: f64| ((j + 180.0) / 360.0).floor() as i64;
    for j in [joints_deg[0], joints_deg[3], joints_deg[5]] {
        let t = turn(j);
        assert!((-180.0..180.0).contains(&(j - 360.0 * t as f64)));
    }
    format!(
        "{} {} {}, {}, {}, {}",
        if joints_deg[4] > 0.0 { 'F' } else { 'N' },
        if front_lower { 'U' } else { 'D' },
        if front1 { 'T' } else { 'B' },
        turn(joints_deg[0]),
        turn(joints_deg[3]),
        turn(joints_deg[5])
    )
}

fn configs(events: &[Ev]) -> Vec<String> {
    events
        .iter()
        .filter_map(|e| match e {
            Ev::Move { config, .. } => Some(config.clone()),
            _ => None,
        })
        .collect()
}

fn numeric_config(s: &str) -> String {
    // "0,-1,2,5" as read from f64 text ("0,-1,2,5" stays).
    s.split(',')
        .map(|v| format!("{}", v.trim().parse::<f64>().unwrap() as i64))
        .collect::<Vec<_>>()
        .join(",")
}

// ------------------------------------------------------------------------------------------
// Through windcell's reader.

fn reader_events(read: &ReadProgram) -> Vec<Ev> {
    read.steps
        .iter()
        .map(|s| match s {
            Step::Move(t) => Ev::Move {
                joint: t.motion == Motion::Joint,
                position_mm: t.position_mm,
                rotation: quat_matrix(t.orientation),
                config: match t.config {
                    ConfigData::Abb(c) => format!("{},{},{},{}", c.cf1, c.cf4, c.cf6, c.cfx),
                    ConfigData::Kuka(k) => format!("{},{}", k.s, k.t),
                    ConfigData::Fanuc(f) => f.text(),
                    ConfigData::None => String::new(),
                },
                external_deg: t.external_deg,
                speed: t.speed_mm_s,
                time: t.duration_s,
                zone: t.zone.radius_mm(),
            },
            Step::Output { number, on, .. } => Ev::Out(*number, *on),
            Step::Wait { number, on, .. } => Ev::Wait(*number, *on),
        })
        .collect()
}

// ------------------------------------------------------------------------------------------
// The tests.

const RAPID_TOL: Tol = Tol {
    position_mm: 0.01,
    angle_deg: 0.01,
    speed_mm_s: 0.05,
    time_s: Some(5e-5),
    zone_mm: 0.05,
};
const KRL_TOL: Tol = Tol {
    position_mm: 0.01,
    angle_deg: 0.01,
    speed_mm_s: 0.05,
    time_s: None,
    zone_mm: 0.005,
};
const FANUC_TOL: Tol = Tol {
    position_mm: 0.01,
    angle_deg: 0.01,
    // Whole mm/sec and CNT in whole mm.
    speed_mm_s: 0.5,
    time_s: None,
    zone_mm: 0.5,
};
const UR_TOL: Tol = Tol {
    position_mm: 0.001,
    angle_deg: 0.01,
    speed_mm_s: 0.0005,
    time_s: Some(5e-5),
    zone_mm: 0.0005,
};

fn write(
    format: Format,
    path: &ProgramPath,
    model: &str,
    per_file: Option<usize>,
) -> Vec<(String, String)> {
    program::write(
        format,
        path,
        &arm(model),
        WriteOptions {
            targets_per_file: per_file,
        },
    )
    .unwrap()
}

fn check_rapid(path: &ProgramPath, per_file: Option<usize>) {
    let files = write(Format::Rapid, path, "irb2600-12/1.65", per_file);
    assert_eq!(
        files[0].0,
        program::main_file_name(Format::Rapid, &path.name)
    );
    let map = files_map(&files);
    let mut got = Vec::new();
    rapid_events(&map, "SBEND_1", &mut got);
    compare(
        "RAPID (test reader)",
        &got,
        &expected_events(path),
        &RAPID_TOL,
    );
    let rules: Vec<String> = path
        .targets
        .iter()
        .map(|t| abb_rule(&t.joints_deg))
        .collect();
    let read: Vec<String> = configs(&got).iter().map(|c| numeric_config(c)).collect();
    assert_eq!(read, rules, "ABB confdata");
    // Every quaternion printed with q1 ≥ 0.
    for t in files
        .iter()
        .flat_map(|(_, t)| t.lines())
        .filter(|l| l.contains("robtarget"))
    {
        let v = numbers(t.split(":=").nth(1).unwrap().trim_end_matches(';'));
        assert!(v[3] >= 0.0, "{t}");
    }
    let read = program::read(Format::Rapid, &files, None).unwrap();
    let mine = reader_events(&read);
    compare(
        "RAPID (windcell reader)",
        &mine,
        &expected_events(path),
        &RAPID_TOL,
    );
    assert_eq!(configs(&mine), rules);
    assert_eq!(read.main_file, "SBEND_1.mod");
    let tool = read.tool.unwrap();
    assert!(sub(tool.position_mm, TCP_MM).iter().all(|v| v.abs() < 1e-3));
}

fn check_krl(path: &ProgramPath, per_file: Option<usize>) {
    let files = write(Format::Krl, path, "kr16-2", per_file);
    let map = files_map(&files);
    let mut got = Vec::new();
    krl_events(&map, "SBEND_1", &mut got);
    compare("KRL (test reader)", &got, &expected_events(path), &KRL_TOL);
    let rules: Vec<String> = path
        .targets
        .iter()
        .map(|t| kuka_rule(&t.joints_deg))
        .collect();
    let read: Vec<String> = configs(&got).iter().map(|c| numeric_config(c)).collect();
    assert_eq!(read, rules, "KUKA S and T");
    for (name, text) in &files {
        assert!(
            text.lines().count() <= 1400,
            "{name}: {} lines",
            text.lines().count()
        );
    }
    let read = program::read(Format::Krl, &files, None).unwrap();
    let mine = reader_events(&read);
    compare(
        "KRL (windcell reader)",
        &mine,
        &expected_events(path),
        &KRL_TOL,
    );
    assert_eq!(configs(&mine), rules);
}

fn check_fanuc(path: &ProgramPath, per_file: Option<usize>) {
    let files = write(Format::Fanuc, path, "m-20ia", per_file);
    let map = files_map(&files);
    let mut got = Vec::new();
    fanuc_events(&map, "SBEND_1", &mut got);
    compare(
        "FANUC (test reader)",
        &got,
        &expected_events(path),
        &FANUC_TOL,
    );
    let rules: Vec<String> = path
        .targets
        .iter()
        .map(|t| fanuc_rule(&t.joints_deg))
        .collect();
    assert_eq!(configs(&got), rules, "FANUC CONFIG");
    let read = program::read(Format::Fanuc, &files, None).unwrap();
    let mine = reader_events(&read);
    compare(
        "FANUC (windcell reader)",
        &mine,
        &expected_events(path),
        &FANUC_TOL,
    );
    assert_eq!(configs(&mine), rules);
}

fn check_ur(path: &ProgramPath) {
    let files = write(Format::UrScript, path, "ur10e", None);
    assert_eq!(files.len(), 1);
    assert_eq!(
        files[0].0,
        program::main_file_name(Format::UrScript, &path.name)
    );
    let mut got = Vec::new();
    ur_events(&files[0].1, &mut got);
    compare(
        "URScript (test reader)",
        &got,
        &expected_events(path),
        &UR_TOL,
    );
    let read = program::read(Format::UrScript, &files, None).unwrap();
    compare(
        "URScript (windcell reader)",
        &reader_events(&read),
        &expected_events(path),
        &UR_TOL,
    );
}

#[test]
fn rapid_round_trip_on_the_irb_2600() {
    check_rapid(&random_path(&Kin::Opw(&IRB2600), 60, 11, false), None);
    check_rapid(&random_path(&Kin::Opw(&IRB2600), 40, 12, true), None);
}

#[test]
fn krl_round_trip_on_the_kr_16() {
    check_krl(&random_path(&Kin::Opw(&KR16), 60, 21, false), None);
    check_krl(&random_path(&Kin::Opw(&KR16), 40, 22, true), None);
}

#[test]
fn fanuc_round_trip_on_the_m_20ia() {
    check_fanuc(&random_path(&Kin::Opw(&M20IA), 60, 31, false), None);
    check_fanuc(&random_path(&Kin::Opw(&M20IA), 40, 32, true), None);
}

#[test]
fn urscript_round_trip_on_the_ur10e() {
    check_ur(&random_path(&Kin::Ur, 80, 41, false));
}

/// Split programs run their parts in order, through both readers.
#[test]
fn split_programs_run_their_parts_in_order() {
    let p = random_path(&Kin::Opw(&IRB2600), 47, 51, false);
    check_rapid(&p, Some(10));
    let files = write(Format::Rapid, &p, "irb2600-12/1.65", Some(10));
    assert_eq!(files.len(), 6);
    let read = program::read(Format::Rapid, &files, None).unwrap();
    assert_eq!(read.files.len(), 6);
    assert_eq!(read.files[0], "SBEND_1.mod");
    assert_eq!(read.files[1], "SBEND_1_P1.mod");
    check_krl(&random_path(&Kin::Opw(&KR16), 47, 52, false), Some(10));
    check_fanuc(&random_path(&Kin::Opw(&M20IA), 47, 53, true), Some(10));
    // The default split keeps every KRL .src within about 1400 lines.
    check_krl(&random_path(&Kin::Opw(&KR16), 700, 54, false), None);
    let files = write(
        Format::Krl,
        &random_path(&Kin::Opw(&KR16), 700, 54, false),
        "kr16-2",
        None,
    );
    assert!(files.len() > 3, "{} files", files.len());
}

/// The configuration data the crate computes agrees with the crate's own arm presets'
/// configuration on their home poses as the vendors publish them (ABB home cf [0,0,0,0];
/// KUKA HOME {A1 0, A2 −90, A3 90, A4 0, A5 0, A6 0} with S 'B010' plus bit 2 for A5 = 0 (6),
/// T 'B000010' (A2 negative); FANUC home J5 = −90: 'N U T, 0, 0, 0').
#[test]
fn home_poses_give_the_vendors_configuration() {
    use sequences::program::config::{abb_conf, fanuc_config, kuka_status};
    let c = abb_conf(&arm("irb2600-12/1.65"), &[0.0, 0.0, 0.0, 0.0, 30.0, 0.0]);
    assert_eq!((c.cf1, c.cf4, c.cf6, c.cfx), (0, 0, 0, 0));
    let k = kuka_status(&arm("kr16-2"), &[0.0, -90.0, 90.0, 0.0, 0.0, 0.0]);
    assert_eq!((k.s, k.t), (6, 2));
    let f = fanuc_config(&arm("m-20ia"), &[0.0, 0.0, 0.0, 0.0, -90.0, 0.0]);
    assert_eq!(f.text(), "N U T, 0, 0, 0");
}

/// The configuration read back names the branch the joints are on: solving the read pose on
/// that branch gives the planned joints (up to whole turns of axes 4 and 6 and axis 1).
#[test]
fn read_configuration_names_the_planned_branch() {
    for (format, model, kin) in [
        (Format::Rapid, "irb2600-12/1.65", Kin::Opw(&IRB2600)),
        (Format::Krl, "kr16-2", Kin::Opw(&KR16)),
        (Format::Fanuc, "m-20ia", Kin::Opw(&M20IA)),
    ] {
        let a = arm(model);
        let p = random_path(&kin, 30, 111, false);
        let files = write(format, &p, model, None);
        let read = program::read(format, &files, None).unwrap();
        for (t, want) in read.targets().zip(&p.targets) {
            assert_eq!(t.config, ConfigData::of(format, &a, &want.joints_deg));
            let branch = t.config.arm_config(&a).unwrap();
            let planned = a.kind.config_of(&want.joints_deg.map(f64::to_radians));
            assert_eq!(branch, planned, "{format} line {}", t.line);
        }
    }
}

#[test]
fn a_urscript_program_of_a_coupled_mandrel_is_refused() {
    let p = random_path(&Kin::Ur, 5, 61, false);
    let coupled = ProgramPath {
        mandrel: MandrelCoupling::Coupled {
            axis: ExternalAxis {
                number: 1,
                mechanical_unit: "STN1".into(),
            },
        },
        targets: p
            .targets
            .iter()
            .map(|t| ProgramTarget {
                external_deg: Some(0.0),
                ..*t
            })
            .collect(),
        ..p.clone()
    };
    let e = program::write(
        Format::UrScript,
        &coupled,
        &arm("ur10e"),
        WriteOptions::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("coupled mandrel"), "{e}");
    // And an industrial format for a UR arm, or URScript for an OPW arm.
    let e = program::write(Format::Krl, &p, &arm("ur10e"), WriteOptions::default()).unwrap_err();
    assert!(e.to_string().contains("urscript"), "{e}");
    let e = program::write(
        Format::UrScript,
        &p,
        &arm("kr16-2"),
        WriteOptions::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("Universal Robots"), "{e}");
}

/// The byte offset of the first `needle` in `text`, as 1-based line and column.
fn line_col(text: &str, needle: &str) -> (usize, usize) {
    let at = text.find(needle).unwrap();
    let line = text[..at].matches('\n').count() + 1;
    let col = at - text[..at].rfind('\n').map_or(0, |i| i + 1) + 1;
    (line, col)
}

#[test]
fn a_syntax_error_names_file_line_and_column() {
    let cases: [(Format, &str, &str, &str); 4] = [
        (Format::Rapid, "irb2600-12/1.65", "[[", "[[?"),
        (Format::Krl, "kr16-2", "{X ", "{X ?"),
        (Format::Fanuc, "m-20ia", "X = ", "X = mm"),
        (Format::UrScript, "ur10e", "p[", "p[q"),
    ];
    for (format, model, needle, bad) in cases {
        let kin = match format {
            Format::Rapid => Kin::Opw(&IRB2600),
            Format::Krl => Kin::Opw(&KR16),
            Format::Fanuc => Kin::Opw(&M20IA),
            Format::UrScript => Kin::Ur,
        };
        let p = random_path(&kin, 6, 71, false);
        let mut files = write(format, &p, model, None);
        // Break the file holding the first target's numbers (the .dat for KRL).
        let k = files.iter().position(|(n, t)| {
            t.contains(needle) && (format != Format::Krl || n.ends_with(".dat"))
        });
        let k = k.unwrap();
        let text = files[k].1.clone();
        let (line, col) = line_col(&text, needle);
        let broken = text.replacen(needle, bad, 1);
        files[k].1 = broken;
        let e = program::read(format, &files, None).unwrap_err();
        let Error::Parse {
            file,
            line: l,
            column,
            ..
        } = &e
        else {
            panic!("{format}: {e:?}");
        };
        assert_eq!(file.as_ref().unwrap().to_str().unwrap(), files[k].0);
        assert_eq!(*l, line, "{format}: {e}");
        // The column of the bad token: just after the needle.
        assert_eq!(*column, col + needle.chars().count(), "{format}: {e}");
        assert!(
            e.to_string()
                .starts_with(&format!("{}:{line}:", files[k].0)),
            "{e}"
        );
    }
}

#[test]
fn a_missing_part_or_an_unknown_call_is_refused() {
    let p = random_path(&Kin::Opw(&KR16), 25, 81, false);
    let mut files = write(Format::Krl, &p, "kr16-2", Some(10));
    files.retain(|(n, _)| n != "SBEND_1_P2.src");
    let e = program::read(Format::Krl, &files, Some("SBEND_1.src")).unwrap_err();
    assert!(e.to_string().contains("SBEND_1_P2"), "{e}");
    assert!(e.to_string().starts_with("SBEND_1.src:"), "{e}");
}

/// Files saved with CR LF line ends (as Windows tools and controllers keep them) and in lower
/// case where the language ignores case read the same.
#[test]
fn crlf_and_case_are_read_the_same() {
    for (format, model, kin) in [
        (Format::Rapid, "irb2600-12/1.65", Kin::Opw(&IRB2600)),
        (Format::Krl, "kr16-2", Kin::Opw(&KR16)),
        (Format::Fanuc, "m-20ia", Kin::Opw(&M20IA)),
        (Format::UrScript, "ur10e", Kin::Ur),
    ] {
        let p = random_path(&kin, 12, 121, false);
        let files = write(format, &p, model, Some(5));
        let want = reader_events(&program::read(format, &files, None).unwrap());
        let crlf: Vec<(String, String)> = files
            .iter()
            .map(|(n, t)| {
                let t = t.replace('\n', "\r\n");
                // RAPID and KRL keywords are case-insensitive.
                let t = match format {
                    Format::Rapid => t.replace("MoveL", "movel").replace("ENDPROC", "endproc"),
                    Format::Krl => t.replace("LIN ", "lin ").replace("DEF ", "def "),
                    _ => t,
                };
                (n.clone(), t)
            })
            .collect();
        let got = reader_events(&program::read(format, &crlf, None).unwrap());
        assert_eq!(got, want, "{format}");
    }
}

/// Long paths split with the default sizes (RAPID 2000 targets a module, KRL 200, FANUC 1000)
/// and read back whole, in time linear in their length.
#[test]
fn long_programs_split_by_default_and_read_back() {
    for (format, model, kin, parts) in [
        (Format::Rapid, "irb2600-12/1.65", Kin::Opw(&IRB2600), 2 + 1),
        (Format::Krl, "kr16-2", Kin::Opw(&KR16), 2 * 15 + 1),
        (Format::Fanuc, "m-20ia", Kin::Opw(&M20IA), 3 + 1),
        (Format::UrScript, "ur10e", Kin::Ur, 1),
    ] {
        let p = random_path(&kin, 3000, 131, false);
        let started = std::time::Instant::now();
        let files = write(format, &p, model, None);
        assert_eq!(files.len(), parts, "{format}");
        let read = program::read(format, &files, None).unwrap();
        assert_eq!(read.targets().count(), 3000);
        let secs = started.elapsed().as_secs_f64();
        assert!(secs < 10.0, "{format}: {secs} s");
    }
}

/// Routines that call each other many times over without moving stop at the step limit,
/// quickly.
#[test]
fn call_bombs_are_bounded() {
    let started = std::time::Instant::now();
    let body = |callee: &str| {
        (1..=50)
            .map(|i| format!("{i:>4}:  CALL {callee} ;\n"))
            .collect::<String>()
    };
    let mut files = vec![(
        "MAIN.ls".to_string(),
        format!("/PROG  MAIN\n/MN\n{}/POS\n/END\n", body("R1")),
    )];
    for k in 1..=10 {
        let mn = if k < 10 {
            body(&format!("R{}", k + 1))
        } else {
            String::new()
        };
        files.push((
            format!("R{k}.ls"),
            format!("/PROG  R{k}\n/MN\n{mn}/POS\n/END\n"),
        ));
    }
    let e = program::read(Format::Fanuc, &files, None).unwrap_err();
    assert!(e.to_string().contains("steps and calls"), "{e}");
    assert!(
        started.elapsed().as_secs_f64() < 5.0,
        "{:?}",
        started.elapsed()
    );
}

/// Programs as a controller's editor keeps them: comments, blank lines, headers and
/// declarations windcell does not write.
#[test]
fn editor_additions_are_read() {
    let p = random_path(&Kin::Opw(&IRB2600), 8, 91, false);
    let files = write(Format::Rapid, &p, "irb2600-12/1.65", None);
    let text = files[0]
        .1
        .replace("CONST robtarget", "LOCAL PERS robtarget");
    let text = format!(
        "%%%\n  VERSION:1\n  LANGUAGE:ENGLISH\n%%%\n\n{}",
        text.replace(
            "  PROC main()",
            "  ! taught by hand\n  VAR num nCount := 0;\n\n  PROC main()\n    ! start"
        )
    );
    let read = program::read(Format::Rapid, &[(files[0].0.clone(), text)], None).unwrap();
    compare(
        "RAPID edited",
        &reader_events(&read),
        &expected_events(&p),
        &RAPID_TOL,
    );

    let p = random_path(&Kin::Opw(&KR16), 8, 92, false);
    let files = write(Format::Krl, &p, "kr16-2", None);
    let files: Vec<(String, String)> = files
        .into_iter()
        .map(|(n, t)| {
            let t = if n.ends_with(".dat") {
                t.replace(
                    "ENDDAT",
                    ";FOLD EXTERNAL DECLARATIONS\nDECL FDAT FP1={TOOL_NO 1,BASE_NO 0,IPO_FRAME #BASE}\nDECL LDAT LCPDAT1={VEL 2.0,ACC 100.0,APO_DIST 100.0}\n;ENDFOLD\nENDDAT",
                )
            } else {
                t.replace("&REL 1\n", "&REL 1\n&PARAM TEMPLATE = C:\\KRC\\Roboter\\Template\\vorgabe\n&PARAM EDITMASK = *\n")
                    .replace("  BAS(#INITMOV,0)", "  ;FOLD INI\n  BAS(#INITMOV,0)\n  ;ENDFOLD (INI)\n\n")
            };
            (n, t)
        })
        .collect();
    let read = program::read(Format::Krl, &files, None).unwrap();
    compare(
        "KRL edited",
        &reader_events(&read),
        &expected_events(&p),
        &KRL_TOL,
    );

    let p = random_path(&Kin::Opw(&M20IA), 8, 93, false);
    let files = write(Format::Fanuc, &p, "m-20ia", None);
    let text = files[0].1.replace(
        "PROTECT\t\t= READ_WRITE;\n",
        "PROTECT\t\t= READ_WRITE;\nTCD:  STACK_SIZE\t= 0,\n      TASK_PRIORITY\t= 50,\n      TIME_SLICE\t= 0;\nCREATE\t\t= DATE 26-11-29  TIME 08:00:00;\n",
    ).replace("/MN\n", "/APPL\n\n/MN\n");
    let read = program::read(Format::Fanuc, &[(files[0].0.clone(), text)], None).unwrap();
    compare(
        "FANUC edited",
        &reader_events(&read),
        &expected_events(&p),
        &FANUC_TOL,
    );

    let p = random_path(&Kin::Ur, 8, 94, false);
    let files = write(Format::UrScript, &p, "ur10e", None);
    let text = files[0].1.replace(
        "  set_tcp",
        "  # from the teach pendant\n  set_payload(1.5)\n\n  set_tcp",
    ) + &format!("{}()\n", files[0].0.trim_end_matches(".script"));
    let read = program::read(Format::UrScript, &[(files[0].0.clone(), text)], None).unwrap();
    compare(
        "URScript edited",
        &reader_events(&read),
        &expected_events(&p),
        &UR_TOL,
    );
}

/// Mutations of written programs (characters deleted, inserted, lines dropped, duplicated or
/// cut) read or fail with an error, never panic, in bounded time.
#[test]
fn mutated_programs_read_or_fail_without_panic() {
    let started = std::time::Instant::now();
    let mut rng = Rng(0x5eed_1234_abcd_0001);
    for (format, model, kin) in [
        (Format::Rapid, "irb2600-12/1.65", Kin::Opw(&IRB2600)),
        (Format::Krl, "kr16-2", Kin::Opw(&KR16)),
        (Format::Fanuc, "m-20ia", Kin::Opw(&M20IA)),
        (Format::UrScript, "ur10e", Kin::Ur),
    ] {
        let p = random_path(&kin, 14, 101, false);
        let files = write(format, &p, model, Some(6));
        for _ in 0..400 {
            let mut mutated = files.clone();
            let k = (rng.unit() * mutated.len() as f64) as usize % mutated.len();
            let text = &mutated[k].1;
            let chars: Vec<char> = text.chars().collect();
            let at = (rng.unit() * chars.len() as f64) as usize % chars.len().max(1);
            let new: String = match (rng.unit() * 6.0) as usize {
                0 => chars
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| *i != at)
                    .map(|(_, c)| *c)
                    .collect(),
                1 => {
                    let pool = [
                        '[', ']', '{', '}', ',', ';', '"', '\'', '\n', '-', 'é', '\0', '9', ':',
                        '(', ')', '%',
                    ];
                    let c = pool[(rng.unit() * pool.len() as f64) as usize % pool.len()];
                    chars[..at]
                        .iter()
                        .chain([c].iter())
                        .chain(chars[at..].iter())
                        .collect()
                }
                2 => chars[..at].iter().collect(),
                3 => {
                    let lines: Vec<&str> = text.lines().collect();
                    let l = at % lines.len().max(1);
                    lines
                        .iter()
                        .enumerate()
                        .filter(|(i, _)| *i != l)
                        .map(|(_, s)| format!("{s}\n"))
                        .collect()
                }
                4 => {
                    let lines: Vec<&str> = text.lines().collect();
                    let l = at % lines.len().max(1);
                    lines
                        .iter()
                        .enumerate()
                        .flat_map(|(i, s)| {
                            if i == l {
                                vec![format!("{s}\n"), format!("{s}\n")]
                            } else {
                                vec![format!("{s}\n")]
                            }
                        })
                        .collect()
                }
                _ => text.replacen(|c: char| c.is_ascii_digit(), "1e999", 1),
            };
            mutated[k].1 = new;
            let _ = program::read(format, &mutated, None);
        }
    }
    assert!(
        started.elapsed().as_secs_f64() < 20.0,
        "{:?}",
        started.elapsed()
    );
}

#[test]
fn a_garbage_file_is_an_error() {
    for format in Format::ALL {
        for text in [
            "",
            "\0\0\0",
            "MODULE",
            "DEF X(",
            "/PROG",
            "def f():\n movel(",
            "]]]]]]",
            &"[".repeat(10_000),
        ] {
            let ext = format.extensions()[0];
            let r = program::read(format, &[(format!("X.{ext}"), text.to_string())], None);
            assert!(r.is_err(), "{format}: {text:?} read as {r:?}");
        }
    }
    let _ = Zone::Fine;
}
