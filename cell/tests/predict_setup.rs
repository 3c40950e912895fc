//! The setup Monte Carlo of `windcell predict` draws each calibration tolerance it is given:
//! the mandrel axis displaced, or leaning, by up to 2 mm moves where the fibre lands by a
//! comparable amount, while with every tolerance zero the samples do not spread at all.

use std::path::Path;

use cell::cellfile::Cell;
use cell::coordinator::RunMode;
use cell::predict::{self, Mode, Options, Tolerances};
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
