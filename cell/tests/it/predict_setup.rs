//! `windcell predict` winds on a cell built from the job: its drive, and a setup Monte Carlo that
//! draws each calibration tolerance it is given:
//! the mandrel axis displaced, or leaning, by up to 2 mm moves where the fibre lands by a
//! comparable amount, while with every tolerance zero the samples do not spread at all.

use crate::common;

use std::path::Path;

use cell::predict::{self, Mode, Options, Tolerances};
use cell::run::cellfile::Cell;
use cell::run::coordinator::RunMode;
use common::{example, example_variant, stderr, windcell};
use sequences::Job;

/// (median, 95th percentile) of the first path's setup error, fine movement on the cylinder.
fn setup_spread(tolerances: Tolerances) -> (f64, f64) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/cylinder.toml");
    let (job, text) = Job::load(&path).unwrap();
    let cell = Cell::of_job(&job, &path).unwrap();
    let opt = Options {
        modes: vec![Mode::Run(RunMode::Fine)],
        samples: 8,
        tolerances,
        ..Options::default()
    };
    let p = predict::predict(&job, &text, &path, &cell, &opt).unwrap();
    let first = &p.modes[0].outcome.as_ref().unwrap()[0];
    (first.setup_median_mm.unwrap(), first.setup_p95_mm.unwrap())
}

#[test]
fn each_tolerance_spreads_the_setup_samples() {
    let zero = Tolerances {
        axis_offset_mm: [0.0, 0.0],
        axis_tilt_rad: [0.0, 0.0],
        zero_angle_rad: 0.0,
        diameter_mm: 0.0,
    };
    let (m0, p0) = setup_spread(zero);
    assert!(
        (p0 - m0).abs() < 1e-9,
        "no tolerance, no spread: {m0} / {p0}"
    );
    // The axis up to 2 mm off in x and y: the tangent point moves with it.
    let (_, p_offset) = setup_spread(Tolerances {
        axis_offset_mm: [2.0, 2.0],
        ..zero
    });
    // Leaning by up to 2 mm over the 178 mm mandrel.
    let lean = (2.0f64 / 178.0).atan();
    let (_, p_tilt) = setup_spread(Tolerances {
        axis_tilt_rad: [lean, lean],
        ..zero
    });
    for (what, p) in [("offset", p_offset), ("tilt", p_tilt)] {
        assert!(
            p > m0 + 0.3,
            "{what}: 95th percentile {p} mm against {m0} mm with no tolerance"
        );
        assert!(
            p < m0 + 4.0,
            "{what}: {p} mm: more than the 2 mm drawn can explain"
        );
    }
}

/// The simulated cell that `predict` winds on has the job's drive: with a 13:39 belt instead of
/// the thesis's 13:60 the control files step the motor 1 200 times per mandrel turn instead of
/// 1 846, and the cylinder's fine winding lays its fibre as closely as with the thesis's drive (a
/// cell simulated with another drive would turn the mandrel by 39/60 of each commanded angle).
#[test]
fn the_simulated_cell_has_the_jobs_drive() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/cylinder.toml");
    let thesis = std::fs::read_to_string(&path).unwrap();
    assert!(thesis.contains("gear_ratio = [13, 60]"));
    let other = thesis.replace("gear_ratio = [13, 60]", "gear_ratio = [13, 39]");
    let first_error = |text: &str| -> f64 {
        let job = Job::parse(text).unwrap();
        let cell = Cell::of_job(&job, &path).unwrap();
        let opt = Options {
            modes: vec![Mode::Run(RunMode::Fine)],
            samples: 0,
            ..Options::default()
        };
        let p = predict::predict(&job, text, &path, &cell, &opt).unwrap();
        p.modes[0].outcome.as_ref().unwrap()[0].max_error_mm
    };
    let (a, b) = (first_error(&thesis), first_error(&other));
    assert!(a < 3.0 && b < 3.0, "13:60 {a} mm, 13:39 {b} mm");
    assert!((a - b).abs() < 1.0, "13:60 {a} mm, 13:39 {b} mm");
}

/// A drive the simulated motor cannot follow (50 mandrel rev/s² to 1 rev/s: at the motor
/// 50 × 60/13 × 400 = 92 300 half-steps/s², a demand the M112 model's pull-out torque does not
/// meet on the way to 1 rev/s) is reported by `windcell predict` in one line that names
/// the stall and both of its possible causes, not a debug dump of the coordinator's halt.
#[test]
fn a_drive_the_motor_cannot_follow_is_reported_as_a_stall() {
    let dir = tempfile::tempdir().unwrap();
    let job = example_variant(
        dir.path(),
        "cylinder.toml",
        "fast.toml",
        &[
            ("accel_rps2 = 1.0", "accel_rps2 = 50.0"),
            ("mandrel_speed_rps = 0.1 ", "mandrel_speed_rps = 1.0 "),
        ],
    );
    let o = windcell(&[
        "predict",
        job.to_str().unwrap(),
        "--mode",
        "fine",
        "--samples",
        "1",
    ]);
    // The job's profile is at fault: exit code 2, the line placed at its acceleration.
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert_eq!(err.lines().count(), 1, "{err}");
    let accel_at = format!("{}:17:14: ", job.display());
    assert!(err.contains(&accel_at), "{err}");
    assert!(err.contains("stalled"), "{err}");
    assert!(err.contains("pull-out torque"), "{err}");
    assert!(!err.contains("Fault {"), "{err}");
}

/// `--cell` with a drive the job was not planned for (quarter steps for the job's half steps)
/// is refused in one line, exit code 2: its simulated mandrel would turn through other angles.
#[test]
fn a_cell_with_another_drive_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let cell = example_variant(
        dir.path(),
        "cell-sim.toml",
        "cell800.toml",
        &[("steps_per_rev = 400", "steps_per_rev = 800")],
    );
    let o = windcell(&[
        "predict",
        example("cylinder.toml").to_str().unwrap(),
        "--cell",
        cell.to_str().unwrap(),
        "--samples",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("800 steps/rev, 13:60 belt) is not the one"),
        "{err}"
    );
    assert!(o.stdout.is_empty());
}

/// A prediction in which one mode asked for can wind and another cannot reports both and
/// succeeds: the refusal is the prediction for that mode (on the 3-radius offset at 1 rev/s the
/// fine program asks the arm for more than its speed; discrete movement waits for it). When
/// no mode can wind, `bad_input`'s corpus holds the one-line refusal with exit code 2.
#[test]
fn a_mode_that_cannot_wind_is_reported_beside_one_that_can() {
    let o = windcell(&[
        "predict",
        example("offset-3r.toml").to_str().unwrap(),
        "--mandrel-rps",
        "1",
        "--mode",
        "discrete",
        "--mode",
        "fine",
        "--samples",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).unwrap();
    assert!(out.contains("discrete at 1 rev/s: "), "{out}");
    assert!(!out.contains("discrete at 1 rev/s: cannot wind"), "{out}");
    assert!(out.contains("fine at 1 rev/s: cannot wind: "), "{out}");
    assert!(out.contains("the eye would have to move at"), "{out}");
}

/// A stall is the prediction for the job's figures, not a fault of the prediction: the same
/// 50 rev/s² ramp that stalls the motor on the way to 1 rev/s is predicted at 0.05 rev/s, where
/// the ramp ends within the motor's pull-out torque.
#[test]
fn a_stall_depends_on_the_speed_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let job = example_variant(
        dir.path(),
        "cylinder.toml",
        "steep.toml",
        &[("accel_rps2 = 1.0", "accel_rps2 = 50.0")],
    );
    for (rps, stalls) in [("1.0", true), ("0.05", false)] {
        let o = windcell(&[
            "predict",
            job.to_str().unwrap(),
            "--mode",
            "fine",
            "--mandrel-rps",
            rps,
            "--samples",
            "1",
        ]);
        assert_eq!(
            o.status.code(),
            Some(if stalls { 2 } else { 0 }),
            "{rps}: {}",
            stderr(&o)
        );
    }
}

/// The line `predict` prints on how far it can be trusted quotes `docs/validation.md`'s
/// held-out figures (1-rev reading): the error band's rows and the discrete times' rows.
#[test]
fn the_validation_line_quotes_the_measured_figures() {
    let doc = include_str!("../../../docs/validation.md");
    let row = |target: &str| -> String {
        doc.lines()
            .find(|l| l.starts_with(&format!("| {target}")))
            .and_then(|l| l.split('|').nth(2))
            .map(|c| c.trim().to_string())
            .unwrap_or_else(|| panic!("validation.md has no row for {target}"))
    };
    let band = row("error within max(1 mm, 40 % of the measured mean)");
    let times = row("discrete total time within ±20 %");
    let line = cell::predict::VALIDATION_LINE;
    let (hit, of) = band.split_once(' ').unwrap().0.split_once('/').unwrap();
    assert!(
        line.contains(&format!("{hit} of them")) && line.contains(of),
        "{band} / {line}"
    );
    let (hit, of) = times.split_once('/').unwrap();
    assert!(line.contains(&format!("{hit} of {of}")), "{times} / {line}");
}
