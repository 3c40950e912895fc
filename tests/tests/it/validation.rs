//! The prediction against the thesis's 378 windings (seed 001 App. B, Tables 1–14; transcribed in
//! `tests/data/appendix-b.csv`), held out honestly: the free constants (the mandrel drive's
//! acceleration, which the thesis does not give, and the scale of the cell's calibration
//! tolerances in the setup Monte Carlo) are fitted on configuration 1 only (Tables 1–2, the
//! axis-symmetric cylinder); Tables 3–14 are then predicted without refitting.
//!
//! Both readings of the revolutions per pass are predicted: the text's 48.3° on the 63.5 × 178 mm
//! cylinder turns 1.0015 rev per pass; App. B's fine and medium times are 2 rev ÷ speed, which a
//! pass of 2 rev (a wind angle of 65.97°) would take. The S-bend (Tables 13–14) is wound as the
//! job describes it under both readings.
//!
//! `WINDCELL_VALIDATION_OUT=DIR cargo test -p tests --test validation -- --nocapture` also writes
//! the side-by-side table (`validation-table.md`) and the scatter plots (`validation-error.svg`,
//! `validation-time.svg`) into `DIR` (docs/validation.md is made from them).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use cell::predict::{self, Mode, Options, Tolerances};
use cell::run::cellfile::Cell;
use cell::run::coordinator::RunMode;
use sequences::Job;

#[derive(Debug, Clone)]
struct Row {
    table: u32,
    config: String,
    direction: String,
    mode: String,
    speed: String,
    errors_mm: [f64; 3],
    mandrel_rps: f64,
    time_s: f64,
}

impl Row {
    fn mean_mm(&self) -> f64 {
        self.errors_mm.iter().sum::<f64>() / 3.0
    }
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn rows() -> Vec<Row> {
    let text = std::fs::read_to_string(repo().join("tests/data/appendix-b.csv")).unwrap();
    let mut out = Vec::new();
    for line in text.lines() {
        if line.starts_with('#') || line.starts_with("table") || line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), 10, "{line}");
        let num = |s: &str| s.trim().parse::<f64>().unwrap();
        out.push(Row {
            table: f[0].parse().unwrap(),
            config: f[1].into(),
            direction: f[2].into(),
            mode: f[3].into(),
            speed: f[4].into(),
            errors_mm: [num(f[5]), num(f[6]), num(f[7])],
            mandrel_rps: num(f[8]),
            time_s: num(f[9]),
        });
    }
    out
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Reading {
    OneRev,
    TwoRev,
}

impl Reading {
    fn name(self) -> &'static str {
        match self {
            Reading::OneRev => "1 rev",
            Reading::TwoRev => "2 rev",
        }
    }
}

/// The wind angle at which a pass over the 178 mm cylinder of radius 31.75 mm turns `revs`.
fn wind_angle_deg(revs: f64) -> f64 {
    (revs * std::f64::consts::TAU * 31.75 / 178.0)
        .atan()
        .to_degrees()
}

/// The model's free constants, fitted on configuration 1 only.
#[derive(Debug, Clone, Copy)]
struct Fitted {
    /// The mandrel drive's acceleration, mandrel rev/s² (`[cell.drive] accel_rps2`).
    accel_rps2: f64,
    /// The setup Monte Carlo's tolerances.
    tol: Tolerances,
}

fn job(config: &str, reading: Reading, accel_rps2: f64) -> (Job, String, PathBuf) {
    let file = repo().join(format!("examples/{config}.toml"));
    let mut text = std::fs::read_to_string(&file).unwrap();
    assert!(text.contains("accel_rps2 = 1.0"));
    text = text.replace("accel_rps2 = 1.0", &format!("accel_rps2 = {accel_rps2:.3}"));
    if config != "sbend" && reading == Reading::TwoRev {
        assert!(text.contains("wind_angle_deg = 48.3"));
        text = text.replace(
            "wind_angle_deg = 48.3",
            &format!("wind_angle_deg = {:.4}", wind_angle_deg(2.0)),
        );
    }
    (Job::parse(&text).unwrap(), text, file)
}

#[derive(Debug, Clone, Copy, Default)]
struct Predicted {
    time_s: f64,
    median_mm: f64,
    p95_mm: f64,
    error: bool,
}

/// Monte Carlo samples per path (the validation's; `predict` defaults to 200).
const SAMPLES: usize = 8;

/// Predicts every row of `rows` (one configuration) under `reading` with tolerances `tol`.
fn predict_rows(rows: &[&Row], reading: Reading, fit: Fitted) -> Vec<Predicted> {
    let tol = fit.tol;
    let config = &rows[0].config;
    let (job, text, file) = job(config, reading, fit.accel_rps2);
    let cell = Cell::of_job(&job, &file).unwrap();
    let mut cache: BTreeMap<(String, u64), Vec<Predicted>> = BTreeMap::new();
    rows.iter()
        .map(|r| {
            let key = (r.mode.clone(), (r.mandrel_rps * 1000.0).round() as u64);
            let paths = cache.entry(key).or_insert_with(|| {
                let mode = RunMode::from_keyword(&r.mode).unwrap();
                let opt = Options {
                    modes: vec![Mode::Run(mode)],
                    mandrel_rps: Some(r.mandrel_rps),
                    samples: SAMPLES,
                    tolerances: tol,
                    step_s: 5e-3,
                    ..Options::default()
                };
                // A run the simulated cell refuses or stops (a stalled motor) is a prediction
                // that the row cannot be wound as given.
                let outcome = predict::predict(&job, &text, &file, &cell, &opt)
                    .map_err(|e| e.to_string())
                    .and_then(|p| p.modes[0].outcome.clone().map_err(|e| e.to_string()));
                match &outcome {
                    Ok(paths) => paths
                        .iter()
                        .map(|p| Predicted {
                            time_s: p.time_s,
                            median_mm: p.setup_median_mm.unwrap_or(p.max_error_mm),
                            p95_mm: p.setup_p95_mm.unwrap_or(p.max_error_mm),
                            error: false,
                        })
                        .collect(),
                    Err(e) => {
                        eprintln!(
                            "{config} {} {} rev/s ({}): {e}",
                            r.mode,
                            r.mandrel_rps,
                            reading.name()
                        );
                        vec![
                            Predicted {
                                error: true,
                                ..Predicted::default()
                            };
                            2
                        ]
                    }
                }
            });
            // Program 1 winds down, program 2 up (examples/*.toml).
            paths[usize::from(r.direction == "up")]
        })
        .collect()
}

fn hit(r: &Row, p: &Predicted) -> bool {
    !p.error && (p.median_mm - r.mean_mm()).abs() <= (0.4 * r.mean_mm()).max(1.0)
}

fn time_hit(r: &Row, p: &Predicted) -> bool {
    !p.error && (p.time_s - r.time_s).abs() <= 0.2 * r.time_s
}

struct Scores {
    error_hits: usize,
    rows: usize,
    discrete_time_hits: usize,
    discrete_rows: usize,
    order_tables: (usize, usize),
    rise: (usize, usize),
    mean_abs_time_ratio_fm: f64,
}

fn mode_index(m: &str) -> usize {
    match m {
        "discrete" => 0,
        "fine" => 1,
        _ => 2,
    }
}

fn score(rows: &[&Row], preds: &[Predicted]) -> Scores {
    let mut s = Scores {
        error_hits: 0,
        rows: rows.len(),
        discrete_time_hits: 0,
        discrete_rows: 0,
        order_tables: (0, 0),
        rise: (0, 0),
        mean_abs_time_ratio_fm: 0.0,
    };
    let mut fm = Vec::new();
    for (r, p) in rows.iter().zip(preds) {
        s.error_hits += usize::from(hit(r, p));
        if r.mode == "discrete" {
            s.discrete_rows += 1;
            s.discrete_time_hits += usize::from(time_hit(r, p));
        } else if !p.error {
            fm.push(p.time_s / r.time_s);
        }
    }
    s.mean_abs_time_ratio_fm = fm.iter().sum::<f64>() / fm.len().max(1) as f64;
    // Per table: the order of the modes' mean errors, and the rise with speed per mode.
    let mut tables: BTreeMap<u32, Vec<(usize, &Row, &Predicted)>> = BTreeMap::new();
    for (r, p) in rows.iter().zip(preds) {
        tables
            .entry(r.table)
            .or_default()
            .push((mode_index(&r.mode), r, p));
    }
    for list in tables.values() {
        let mut measured = [0.0; 3];
        let mut predicted = [0.0; 3];
        for (m, r, p) in list {
            measured[*m] += r.mean_mm();
            predicted[*m] += p.median_mm;
        }
        if measured[0] < measured[1] && measured[1] < measured[2] {
            s.order_tables.1 += 1;
            if predicted[0] < predicted[1] && predicted[1] < predicted[2] {
                s.order_tables.0 += 1;
            }
        }
        for m in 0..3 {
            let of: Vec<_> = list.iter().filter(|x| x.0 == m).collect();
            let (Some(v1), Some(v3)) = (
                of.iter().find(|x| x.1.speed == "v1"),
                of.iter().find(|x| x.1.speed == "v3"),
            ) else {
                continue;
            };
            if v3.1.mean_mm() > v1.1.mean_mm() {
                s.rise.1 += 1;
                if v3.2.median_mm > v1.2.median_mm {
                    s.rise.0 += 1;
                }
            }
        }
    }
    s
}

/// The fitted constant: the scale of the thesis cell's tolerances that brings the predicted
/// median nearest the measured mean on configuration 1 (least absolute deviation over its 18
/// rows). Only configuration-1 rows reach this function.
fn fit_scale(config1: &[&Row], reading: Reading, accel_rps2: f64) -> (f64, f64) {
    assert!(config1.iter().all(|r| r.table <= 2));
    least([0.0, 1.0, 3.0, 9.0], |k| {
        let fit = Fitted {
            accel_rps2,
            tol: Tolerances::default().scaled(k),
        };
        let preds = predict_rows(config1, reading, fit);
        config1
            .iter()
            .zip(&preds)
            .map(|(r, p)| (p.median_mm - r.mean_mm()).abs())
            .sum::<f64>()
            / config1.len() as f64
    })
}

/// The candidate of least cost (the first of equals) and its cost.
fn least<const N: usize>(candidates: [f64; N], mut cost: impl FnMut(f64) -> f64) -> (f64, f64) {
    let mut best = (candidates[0], f64::INFINITY);
    for c in candidates {
        let e = cost(c);
        if e < best.1 {
            best = (c, e);
        }
    }
    best
}

/// Candidate mandrel accelerations, rev/s². The thesis gives none (the mandrel instruction
/// carries one, §5.6.2; the examples' 1 rev/s² is ours), yet App. B's discrete rows run the
/// mandrel "at" 1–3 rev/s in segments of 0.02–0.04 rev, which 1 rev/s² never reaches. Up to
/// 16 rev/s² (74 motor rev/s², below the simulated motor's pull-out limit at these speeds).
const ACCELS_RPS2: [f64; 5] = [1.0, 2.0, 4.0, 8.0, 16.0];

/// The fitted drive acceleration: the candidate whose predicted discrete times come nearest
/// App. B's on configuration 1 (least mean relative deviation over its 6 discrete rows; the
/// fine and medium times are computed in App. B, and the errors hardly depend on it). Only
/// configuration-1 rows reach this function. Returns (acceleration, mean relative deviation).
fn fit_accel(config1: &[&Row], reading: Reading) -> (f64, f64) {
    assert!(config1.iter().all(|r| r.table <= 2));
    let discrete: Vec<&Row> = config1
        .iter()
        .copied()
        .filter(|r| r.mode == "discrete")
        .collect();
    least(ACCELS_RPS2, |a| {
        let fit = Fitted {
            accel_rps2: a,
            tol: Tolerances::default(),
        };
        let preds = predict_rows(&discrete, reading, fit);
        discrete
            .iter()
            .zip(&preds)
            .map(|(r, p)| {
                if p.error {
                    f64::INFINITY
                } else {
                    (p.time_s - r.time_s).abs() / r.time_s
                }
            })
            .sum::<f64>()
            / discrete.len() as f64
    })
}

#[test]
fn appendix_b_held_out() {
    let all = rows();
    assert_eq!(all.len(), 126, "14 tables × 3 modes × 3 speeds");
    let config1: Vec<&Row> = all.iter().filter(|r| r.table <= 2).collect();
    let held: Vec<&Row> = all.iter().filter(|r| r.table > 2).collect();
    assert_eq!((config1.len(), held.len()), (18, 108));
    // The two readings are independent: one thread each (the machine's two cores).
    let one_reading = |reading: Reading| {
        let mut report = String::new();
        let (accel_rps2, accel_cost) = fit_accel(&config1, reading);
        let (k, fit_cost) = fit_scale(&config1, reading, accel_rps2);
        let fit = Fitted {
            accel_rps2,
            tol: Tolerances::default().scaled(k),
        };
        let mut preds = predict_rows(&config1, reading, fit);
        let mut by_config: BTreeMap<&str, Vec<&Row>> = BTreeMap::new();
        for r in &held {
            by_config.entry(r.config.as_str()).or_default().push(r);
        }
        let mut held_rows = Vec::new();
        let mut held_preds = Vec::new();
        for rs in by_config.values() {
            held_preds.extend(predict_rows(rs, reading, fit));
            held_rows.extend(rs.iter().copied());
        }
        let s = score(&held_rows, &held_preds);
        let c1 = score(&config1, &preds);
        let _ = writeln!(
            report,
            "{}: drive acceleration {accel_rps2} rev/s² (config 1 discrete times off by {:.0} % \
             on average); tolerance scale {k} (config 1 mean |median − measured| \
             {fit_cost:.2} mm); \
             held out: error within max(1 mm, 40 %) on {}/{} rows ({:.0} %); discrete times \
             within ±20 % on {}/{}; fine/medium time ÷ App. B {:.2}; order discrete < fine < \
             medium on {}/{} tables that have it; rise with speed on {}/{}; config 1: error hits \
             {}/{}, discrete times {}/{}",
            reading.name(),
            100.0 * accel_cost,
            s.error_hits,
            s.rows,
            100.0 * s.error_hits as f64 / s.rows as f64,
            s.discrete_time_hits,
            s.discrete_rows,
            s.mean_abs_time_ratio_fm,
            s.order_tables.0,
            s.order_tables.1,
            s.rise.0,
            s.rise.1,
            c1.error_hits,
            c1.rows,
            c1.discrete_time_hits,
            c1.discrete_rows,
        );
        // Every row in table order.
        let mut order: Vec<(&Row, Predicted)> =
            config1.iter().copied().zip(preds.drain(..)).collect();
        order.extend(held_rows.iter().copied().zip(held_preds));
        order.sort_by_key(|(r, _)| (r.table, mode_index(&r.mode), r.speed.clone()));
        // Every row was predicted or refused with a reason.
        assert_eq!(order.len(), 126);
        (report, (k, s, order))
    };
    let (one, two) = std::thread::scope(|scope| {
        let one = scope.spawn(|| one_reading(Reading::OneRev));
        let two = one_reading(Reading::TwoRev);
        (one.join().unwrap(), two)
    });
    let report = format!("{}{}", one.0, two.0);
    let mut results = BTreeMap::new();
    results.insert(Reading::OneRev, one.1);
    results.insert(Reading::TwoRev, two.1);
    eprintln!("{report}");
    let out = std::env::var_os("WINDCELL_VALIDATION_OUT").map(PathBuf::from);
    if let Some(dir) = out {
        write_outputs(&dir, &report, &results);
    }
    // The fine and medium times of App. B are 2 rev ÷ speed: the 2-rev reading reproduces them
    // (the mandrel's one move sets the time; its ramps add a little), the 1-rev reading takes
    // well under (half, plus the ramps and the robot's lag). The fit cannot change a time.
    let two = &results[&Reading::TwoRev].1;
    let one = &results[&Reading::OneRev].1;
    assert!(
        (two.mean_abs_time_ratio_fm - 1.0).abs() < 0.1,
        "{}",
        two.mean_abs_time_ratio_fm
    );
    assert!(
        one.mean_abs_time_ratio_fm < 0.8,
        "{}",
        one.mean_abs_time_ratio_fm
    );
    // The rise of error with speed (a regression guard at the figures docs/validation.md gives).
    assert!(
        one.rise.0 * 4 >= one.rise.1 * 3,
        "{}/{}",
        one.rise.0,
        one.rise.1
    );
}

/// Per reading: the fitted scale, the held-out scores, every row with its prediction.
type Results<'a> = BTreeMap<Reading, (f64, Scores, Vec<(&'a Row, Predicted)>)>;

fn write_outputs(dir: &Path, report: &str, results: &Results<'_>) {
    std::fs::create_dir_all(dir).unwrap();
    let mut md = String::new();
    let _ = writeln!(md, "<!-- written by tests/tests/validation.rs -->\n");
    for line in report.lines() {
        let _ = writeln!(md, "- {line}");
    }
    let _ = writeln!(
        md,
        "\n| table | configuration | dir | mode | speed | rev/s | measured error, mm (3 runs; mean) | \
         predicted 1 rev: median / p95 | predicted 2 rev: median / p95 | measured time, s | \
         predicted time 1 rev / 2 rev, s | hit 1 rev / 2 rev |\n|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    let one = &results[&Reading::OneRev].2;
    let two = &results[&Reading::TwoRev].2;
    for ((r, a), (_, b)) in one.iter().zip(two) {
        let fmt = |p: &Predicted| {
            if p.error {
                "refused".to_string()
            } else {
                format!("{:.2} / {:.2}", p.median_mm, p.p95_mm)
            }
        };
        let mark = |p: &Predicted| if hit(r, p) { "✓" } else { "✗" };
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {:.2} | {:.1}, {:.1}, {:.1}; {:.2} | {} | {} | {:.1} | {:.1} / {:.1} | {} / {} |",
            r.table,
            r.config,
            r.direction,
            r.mode,
            r.speed,
            r.mandrel_rps,
            r.errors_mm[0],
            r.errors_mm[1],
            r.errors_mm[2],
            r.mean_mm(),
            fmt(a),
            fmt(b),
            r.time_s,
            a.time_s,
            b.time_s,
            mark(a),
            mark(b),
        );
    }
    std::fs::write(dir.join("validation-table.md"), md).unwrap();
    scatter(
        &dir.join("validation-error.svg"),
        "placement error: predicted median against measured mean (mm)",
        results,
        |r, p| (r.mean_mm(), p.median_mm),
    );
    scatter(
        &dir.join("validation-time.svg"),
        "total time: predicted against App. B (s)",
        results,
        |r, p| (r.time_s, p.time_s),
    );
}

fn scatter(
    path: &Path,
    title: &str,
    results: &Results<'_>,
    xy: impl Fn(&Row, &Predicted) -> (f64, f64),
) {
    // Plotted by hand as SVG: circles per point, the y = x line, held-out rows filled.
    let mut pts = Vec::new();
    for (reading, (_, _, list)) in results {
        for (r, p) in list {
            if !p.error {
                let (x, y) = xy(r, p);
                pts.push((*reading, r.table > 2, x, y));
            }
        }
    }
    let max = pts.iter().map(|p| p.2.max(p.3)).fold(1.0, f64::max) * 1.05;
    let (w, h, m) = (640.0, 640.0, 60.0);
    let sx = |x: f64| m + x / max * (w - 2.0 * m);
    let sy = |y: f64| h - m - y / max * (h - 2.0 * m);
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\">\n\
         <rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n\
         <text x=\"{}\" y=\"24\" font-family=\"sans-serif\" font-size=\"15\" text-anchor=\"middle\">{title}</text>\n\
         <line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"black\"/>\n\
         <line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"black\"/>\n\
         <line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"grey\" stroke-dasharray=\"4 4\"/>\n",
        w / 2.0,
        sx(0.0),
        sy(0.0),
        sx(max),
        sy(0.0),
        sx(0.0),
        sy(0.0),
        sx(0.0),
        sy(max),
        sx(0.0),
        sy(0.0),
        sx(max),
        sy(max),
    );
    for k in 0..=5 {
        let v = max * k as f64 / 5.0;
        let _ = write!(
            s,
            "<text x=\"{}\" y=\"{}\" font-family=\"sans-serif\" font-size=\"11\" text-anchor=\"middle\">{v:.1}</text>\n\
             <text x=\"{}\" y=\"{}\" font-family=\"sans-serif\" font-size=\"11\" text-anchor=\"end\">{v:.1}</text>\n",
            sx(v),
            sy(0.0) + 16.0,
            sx(0.0) - 6.0,
            sy(v) + 4.0
        );
    }
    let _ = write!(
        s,
        "<text x=\"{}\" y=\"{}\" font-family=\"sans-serif\" font-size=\"12\" text-anchor=\"middle\">measured (App. B)</text>\n\
         <text x=\"16\" y=\"{}\" font-family=\"sans-serif\" font-size=\"12\" transform=\"rotate(-90 16 {})\" text-anchor=\"middle\">predicted</text>\n",
        w / 2.0,
        h - 16.0,
        h / 2.0,
        h / 2.0
    );
    for (reading, held, x, y) in pts {
        let colour = match reading {
            Reading::OneRev => "#1f77b4",
            Reading::TwoRev => "#d62728",
        };
        let fill = if held { colour } else { "none" };
        let _ = writeln!(
            s,
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3.5\" stroke=\"{colour}\" fill=\"{fill}\" fill-opacity=\"0.6\"/>",
            sx(x),
            sy(y)
        );
    }
    let _ = write!(
        s,
        "<circle cx=\"{}\" cy=\"50\" r=\"4\" fill=\"#1f77b4\"/><text x=\"{}\" y=\"54\" font-family=\"sans-serif\" font-size=\"12\">1 rev per pass</text>\n\
         <circle cx=\"{}\" cy=\"70\" r=\"4\" fill=\"#d62728\"/><text x=\"{}\" y=\"74\" font-family=\"sans-serif\" font-size=\"12\">2 rev per pass</text>\n\
         <text x=\"{}\" y=\"94\" font-family=\"sans-serif\" font-size=\"12\">open: configuration 1 (fitted); filled: held out</text>\n</svg>\n",
        m + 10.0,
        m + 20.0,
        m + 10.0,
        m + 20.0,
        m + 10.0
    );
    std::fs::write(path, s).unwrap();
}

/// One linear constraint `coef · x ≤ rhs`.
type Constraint = (Vec<f64>, f64);

/// Fourier–Motzkin elimination of variable `i`: the constraints on the other variables that
/// hold exactly when some value of `i` satisfies all of `cons`.
fn eliminate(cons: &[Constraint], i: usize) -> Vec<Constraint> {
    let (mut lower, mut upper, mut out) = (Vec::new(), Vec::new(), Vec::new());
    for c in cons {
        if c.0[i] > 0.0 {
            upper.push(c);
        } else if c.0[i] < 0.0 {
            lower.push(c);
        } else {
            out.push(c.clone());
        }
    }
    for u in &upper {
        for l in &lower {
            let (wu, wl) = (-l.0[i], u.0[i]);
            let coef: Vec<f64> = (0..u.0.len()).map(|k| u.0[k] * wu + l.0[k] * wl).collect();
            let rhs = u.1 * wu + l.1 * wl;
            // Scaled to its largest coefficient, so that the products stay near 1.
            let s = coef.iter().fold(0.0_f64, |m, x| m.max(x.abs())).max(1e-300);
            out.push((coef.iter().map(|x| x / s).collect(), rhs / s));
        }
    }
    out
}

/// Per held-out configuration and direction, three measures of the robot's motion over a
/// planned pass (1-rev reading, discrete, 1 rev/s): the eye's travel (mm), the joints' travel
/// (the largest joint move of each segment, summed, degrees) and the robot's least time (the
/// plan's, s).
fn motion_measures(config: &str) -> [[f64; 3]; 2] {
    let (job, text, file) = job(config, Reading::OneRev, 8.0);
    let plan = cell::plan::tool::plan(&job, &text, &file).unwrap();
    let mut out = [[0.0; 3]; 2];
    for p in &plan.paths {
        let d = usize::from(p.program == 2);
        let mut prev = &p.plan.start;
        for s in &p.plan.segments {
            out[d][0] += (s.pose.eye_mm - prev.eye_mm).norm();
            let (a, b) = (s.pose.joints.to_array(), prev.joints.to_array());
            out[d][1] += (0..5)
                .map(|k| (a[k] - b[k]).abs().to_degrees())
                .fold(0.0, f64::max);
            out[d][2] += s.robot_time_s;
            prev = &s.pose;
        }
    }
    out
}

/// Why the discrete-time target is out of reach of a time model built on the robot's motion.
/// App. B's held-out discrete times (26–54 s) vary with the configuration far more than the
/// plans' motion does, and not in its order: for each of three measures `m` of the motion, no
/// model `T = a + b·m + c/ω` with `b ≥ 0` (more motion never takes less time), whatever `a`, `b`
/// and `c` — fitted on these very rows — puts every one of the 36 rows within ±20 % (exact
/// Fourier–Motzkin elimination). The best such model a grid search finds is reported.
#[test]
fn discrete_times_follow_no_motion_model() {
    let all = rows();
    let held: Vec<&Row> = all
        .iter()
        .filter(|r| r.table > 2 && r.mode == "discrete")
        .collect();
    assert_eq!(held.len(), 36);
    let mut measures: BTreeMap<&str, [[f64; 3]; 2]> = BTreeMap::new();
    for r in &held {
        measures
            .entry(r.config.as_str())
            .or_insert_with(|| motion_measures(&r.config));
    }
    let measure_of =
        |r: &Row, k: usize| measures[r.config.as_str()][usize::from(r.direction == "up")][k];
    let names = ["eye travel", "joint travel", "robot least time"];
    for (k, name) in names.iter().enumerate() {
        // Variables (a, b, c): 0.8 T ≤ a + b m + c/ω ≤ 1.2 T, and −b ≤ 0.
        let mut cons: Vec<Constraint> = vec![(vec![0.0, -1.0, 0.0], 0.0)];
        for r in &held {
            let (m, u) = (measure_of(r, k), 1.0 / r.mandrel_rps);
            cons.push((vec![1.0, m, u], 1.2 * r.time_s));
            cons.push((vec![-1.0, -m, -u], -0.8 * r.time_s));
        }
        let on_b = eliminate(&eliminate(&cons, 0), 2);
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        let mut contradiction = false;
        for (coef, rhs) in &on_b {
            if coef[1] > 1e-12 {
                hi = hi.min(rhs / coef[1]);
            } else if coef[1] < -1e-12 {
                lo = lo.max(rhs / coef[1]);
            } else if *rhs < -1e-9 {
                contradiction = true;
            }
        }
        // The best model on a grid of (b, c): for each, the `a` that most rows admit.
        let m_max = held.iter().map(|r| measure_of(r, k)).fold(0.0, f64::max);
        let mut best = (0usize, 0.0, 0.0, 0.0);
        for bi in 0..=400 {
            let b = f64::from(bi) / 400.0 * 2.0 * 60.0 / m_max;
            for ci in -100..=100 {
                let c = f64::from(ci) * 0.1;
                let mut ends: Vec<(f64, i32)> = Vec::new();
                for r in &held {
                    let x = b * measure_of(r, k) + c / r.mandrel_rps;
                    ends.push((0.8 * r.time_s - x, -1));
                    ends.push((1.2 * r.time_s - x, 1));
                }
                // Sorted with openings before closings at equal values.
                ends.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.1.cmp(&q.1)));
                let mut n = 0i32;
                for (v, e) in ends {
                    n -= e;
                    if n as usize > best.0 {
                        best = (n as usize, v, b, c);
                    }
                }
            }
        }
        eprintln!(
            "discrete times against {name}: b must lie in [{lo:.4}, {hi:.4}] (empty); best on \
             the grid: {}/36 rows with a = {:.2} s, b = {:.4}, c = {:.2} s·rev/s",
            best.0, best.1, best.2, best.3
        );
        assert!(
            contradiction || lo > hi,
            "{name}: some model fits every row (b in [{lo}, {hi}])"
        );
        assert!(best.0 < 36);
    }
}

/// Why the error target is out of reach of the setup Monte Carlo: the tolerance scale `k`
/// fitted on the held-out rows themselves (in sample, which the held-out rule forbids) brings
/// at most a few more rows into the band. Measured, not asserted: about 80 s in a release build
/// (`cargo test --release -p tests --test validation -- --ignored --nocapture`);
/// docs/validation.md quotes its figures.
#[test]
#[ignore = "measurement, 80 s"]
fn setup_scale_fitted_in_sample() {
    let all = rows();
    let mut by_config: BTreeMap<&str, Vec<&Row>> = BTreeMap::new();
    for r in all.iter().filter(|r| r.table > 2) {
        by_config.entry(r.config.as_str()).or_default().push(r);
    }
    for reading in [Reading::OneRev, Reading::TwoRev] {
        for k in [0.0, 0.5, 1.0, 2.0, 3.0, 5.0, 9.0] {
            let fit = Fitted {
                accel_rps2: 8.0,
                tol: Tolerances::default().scaled(k),
            };
            let (mut rs, mut ps) = (Vec::new(), Vec::new());
            for list in by_config.values() {
                ps.extend(predict_rows(list, reading, fit));
                rs.extend(list.iter().copied());
            }
            let s = score(&rs, &ps);
            eprintln!(
                "{} k = {k}: error within the band on {}/{} held-out rows; order {}/{}; rise {}/{}",
                reading.name(),
                s.error_hits,
                s.rows,
                s.order_tables.0,
                s.order_tables.1,
                s.rise.0,
                s.rise.1
            );
        }
    }
}
