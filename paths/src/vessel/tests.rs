use super::*;
use crate::motion::tests::limits;
use crate::motion::{Estimate, Recording};
use approx::assert_abs_diff_eq;

include!("../../tests/data/seed002_o0004.rs");

/// `job` is refused with a message that contains `expect`; the message.
fn refused_with(job: &Job, expect: &str) -> String {
    let err = job.check().unwrap_err().to_string();
    assert!(err.contains(expect), "{err}");
    err
}

pub(crate) fn seed_job(length_mm: f64, advance_deg: Option<f64>) -> Job {
    Job {
        mandrel: Mandrel::Vessel {
            cylinder_radius_mm: 60.0,
            cylinder_length_mm: length_mm,
            polar_radius_mm: 21.0,
        },
        tow: Tow {
            band_mm: 4.0,
            thickness_mm: 0.2,
        },
        machine: Machine {
            axes: AxisSet::Four,
            eye_radius_mm: 90.0,
            limits: limits(),
            dome_steps: 10,
        },
        layers: vec![Layer::Helical(PatternRequest {
            advance_deg,
            ..PatternRequest::default()
        })],
        build_up: true,
    }
}

fn record(job: &Job) -> Recording {
    let mut r = Recording::default();
    job.check().unwrap().emit(&mut r).unwrap();
    r
}

fn increments(moves: &[Move], from: Axes) -> Vec<[f64; 4]> {
    let mut prev = from.to_array();
    moves
        .iter()
        .map(|m| {
            let a = m.to.to_array();
            let d = [
                a[0] - prev[0],
                a[1] - prev[1],
                a[2] - prev[2],
                a[3] - prev[3],
            ];
            prev = a;
            d
        })
        .collect()
}

#[test]
fn tv10_forward_stroke_is_the_appendix_program() {
    let r = record(&seed_job(84.1, Some(15.0)));
    assert_eq!(r.moves[0].kind, MoveKind::Rapid);
    // The start station: the near polar opening, eye at √(λ² + rp²), no rotation.
    assert_abs_diff_eq!(
        r.moves[0].to.carriage_mm,
        -(84.1 / 2.0 + 56.20498),
        epsilon = 1e-5
    );
    assert_abs_diff_eq!(r.moves[0].to.cross_feed_mm, 70.2922, epsilon = 1e-4);
    let d = increments(&r.moves[1..42], r.moves[0].to);
    for (i, (got, want)) in d.iter().zip(APPENDIX_FORWARD.iter()).enumerate() {
        for axis in 0..4 {
            assert!(
                (got[axis] - want[axis]).abs() <= 0.005,
                "move {} axis {axis}: {} vs {}",
                i + 1,
                got[axis],
                want[axis]
            );
        }
    }
    // The backward stroke mirrors carriage and eye (O0005), the mandrel keeps turning forward.
    let back = increments(&r.moves[42..82], r.moves[41].to);
    for (got, want) in back.iter().zip(APPENDIX_FORWARD.iter()) {
        assert!((got[0] - want[0]).abs() <= 0.005);
        assert!((got[1] + want[1]).abs() <= 0.005);
        assert!((got[2] - want[2]).abs() <= 0.005);
        assert!((got[3] + want[3]).abs() <= 0.005);
    }
}

#[test]
fn tv6_layer_of_24_cycles_and_the_advance_on_the_last_move() {
    let job = seed_job(84.1, Some(15.0));
    let plan = job.check().unwrap();
    assert_eq!(plan.layers[0].mark.circuits, 24);
    let r = record(&job);
    // 1 rapid + 24 cycles × 2 strokes × 41 moves.
    assert_eq!(r.moves.len(), 1 + 24 * 82);
    // Cycle 6's last move turns 2.946 + 15 = 17.946° (O0007); cycle 1's turns 2.946 (O0006).
    let d = increments(&r.moves[1..], r.moves[0].to);
    assert_abs_diff_eq!(d[81][0], 2.946, epsilon = 0.005);
    assert_abs_diff_eq!(d[6 * 82 - 1][0], 17.946, epsilon = 0.005);
    // One cycle turns Φ1 = 420.0125°.
    let cycle: f64 = d[..82].iter().map(|x| x[0]).sum();
    assert_abs_diff_eq!(cycle, 420.0125, epsilon = 1e-3);
    // The layer ends back at the near pole, every stroke's Y, Z and A net to zero.
    let end = r.moves.last().unwrap().to;
    assert_abs_diff_eq!(end.carriage_mm, r.moves[0].to.carriage_mm, epsilon = 1e-9);
    assert_abs_diff_eq!(end.eye_deg, 0.0, epsilon = 1e-9);
    // Total turn: 24 cycles of Φ1 plus 4 advances of 15°.
    assert_abs_diff_eq!(end.mandrel_deg, 24.0 * 420.0125 + 60.0, epsilon = 0.01);
}

#[test]
fn tv12_casing_layer_time_is_about_16_minutes_at_f6000() {
    // Seed 002 §3.4: one double angle-ply layer of the Lc = 160 casing took about 16 min with
    // F6000 on the XYZA vector. The same measure over our moves: ±15 %.
    let r = record(&seed_job(160.0, None));
    let mut prev = r.moves[0].to.to_array();
    let mut vector = 0.0;
    for m in &r.moves[1..] {
        let a = m.to.to_array();
        vector += (0..4).map(|i| (a[i] - prev[i]).powi(2)).sum::<f64>().sqrt();
        prev = a;
    }
    let minutes = vector / 6000.0;
    assert!((minutes - 16.0).abs() < 16.0 * 0.15, "{minutes}");
}

#[test]
fn build_up_grows_the_radius_and_closes_each_layer() {
    let mut job = seed_job(160.0, None);
    job.layers = vec![
        Layer::Helical(PatternRequest::default()),
        Layer::Hoop { passes: 1 },
        Layer::Helical(PatternRequest::default()),
    ];
    let plan = job.check().unwrap();
    let radii: Vec<f64> = plan
        .layers
        .iter()
        .map(|l| l.mark.winding_radius_mm)
        .collect();
    assert_abs_diff_eq!(radii[1], 60.4, epsilon = 1e-12);
    assert_abs_diff_eq!(radii[2], 60.6, epsilon = 1e-12);
    // The third layer's wind angle follows Clairaut on the larger radius.
    assert_abs_diff_eq!(
        plan.layers[2].mark.wind_angle_deg,
        (21.0f64 / 60.6).asin().to_degrees(),
        epsilon = 1e-9
    );
    job.build_up = false;
    let flat = job.check().unwrap();
    assert!(flat.layers.iter().all(|l| l.mark.winding_radius_mm == 60.0));
}

#[test]
fn hoop_is_one_move_per_pass_at_one_band_per_turn() {
    let mut job = seed_job(160.0, None);
    job.layers = vec![Layer::Hoop { passes: 2 }];
    let r = record(&job);
    let feeds: Vec<&Move> = r
        .moves
        .iter()
        .zip(&r.moves[1..])
        .filter(|(a, b)| b.kind == MoveKind::Feed && a.to.carriage_mm != b.to.carriage_mm)
        .map(|(_, b)| b)
        .collect();
    assert_eq!(feeds.len(), 2);
    let turn = feeds[0].to.mandrel_deg - r.moves[0].to.mandrel_deg;
    assert_abs_diff_eq!(turn, 160.0 / 4.0 * 360.0, epsilon = 1e-9);
    assert_abs_diff_eq!(feeds[0].to.carriage_mm, 80.0, epsilon = 1e-12);
    assert_abs_diff_eq!(feeds[1].to.carriage_mm, -80.0, epsilon = 1e-12);
    // The eye lies over by 90° − β each way.
    assert!(feeds[0].to.eye_deg > 0.0 && feeds[1].to.eye_deg < 0.0);
}

#[test]
fn two_axis_fallback_keeps_the_eye_radius_and_has_no_rotation() {
    let mut job = seed_job(160.0, None);
    job.machine.axes = AxisSet::Two;
    let r = record(&job);
    for m in &r.moves {
        assert_abs_diff_eq!(m.to.cross_feed_mm, 90.0, epsilon = 1e-9);
        assert_eq!(m.to.eye_deg, 0.0);
    }
    // The stroke still turns Φ1/2 per stroke plus the dwell.
    let plan = job.check().unwrap();
    let p = plan.layers[0].pattern.unwrap();
    let stroke_turn = r.moves[1 + 40].to.mandrel_deg - r.moves[0].to.mandrel_deg;
    assert_abs_diff_eq!(
        stroke_turn,
        p.cycle_angle_deg / 2.0 + p.dwell_deg,
        epsilon = 1e-9
    );
}

#[test]
fn eye_inside_laminate_is_refused() {
    let mut job = seed_job(160.0, None);
    job.machine.eye_radius_mm = 60.5;
    job.layers = vec![Layer::Helical(PatternRequest::default()); 3];
    assert!(matches!(
        job.check(),
        Err(Error::EyeInsideLaminate { layer: 3, .. })
    ));
}

pub(crate) fn tube_job(layers: usize) -> Job {
    Job {
        mandrel: Mandrel::Tube {
            radius_mm: 35.0,
            length_mm: 1460.0,
        },
        tow: Tow {
            band_mm: 6.5,
            thickness_mm: 0.25,
        },
        machine: Machine {
            axes: AxisSet::Four,
            eye_radius_mm: 80.0,
            limits: limits(),
            dome_steps: 10,
        },
        layers: vec![
            Layer::TubeHelical(TubeHelical {
                wind_angle_deg: 45.0,
                pattern_number: 3,
                skip_index: 1,
                lock_deg: 720.0,
                lead_in_mm: 10.0,
                lead_out_deg: 10.0,
                initial_lock: true,
                friction_lambda: 0.0,
            });
            layers
        ],
        build_up: false,
    }
}

#[test]
fn tube_helical_counts_circuits_and_keeps_the_angle() {
    let job = tube_job(1);
    let plan = job.check().unwrap();
    // ceil(2π·35 / (6.5 / cos 45°)) = ceil(23.92) = 24.
    assert_eq!(plan.layers[0].mark.circuits, 24);
    let r = record(&job);
    // Every move that moves the carriage lays at 45°: R·Δθ = Δz·tan 45°.
    let mut prev = r.moves[0].to;
    let mut passes = 0;
    for m in &r.moves[1..] {
        let dz = m.to.carriage_mm - prev.carriage_mm;
        if dz != 0.0 {
            let arc = 35.0 * (m.to.mandrel_deg - prev.mandrel_deg).to_radians();
            assert_abs_diff_eq!(arc, dz.abs(), epsilon = 1e-6);
            if dz.abs() > 100.0 {
                passes += 1;
            }
            // The eye lies at 90° − 45° on the side the carriage travels to.
            assert_abs_diff_eq!(m.to.eye_deg, 45.0 * dz.signum(), epsilon = 1e-9);
        } else {
            // Every turn with the carriage still (lead-out, the turn at each end, the locks)
            // has the eye back at 0.
            assert_eq!(m.to.eye_deg, 0.0);
        }
        assert!(
            m.to.mandrel_deg >= prev.mandrel_deg,
            "the mandrel never turns back"
        );
        prev = m.to;
    }
    assert_eq!(passes, 2 * 24);
    // The tow length of the mark is the surface arc of every move.
    let mut laid = 0.0;
    let mut prev = r.moves[0].to;
    for m in &r.moves[1..] {
        let arc = 35.0 * (m.to.mandrel_deg - prev.mandrel_deg).to_radians();
        laid += (m.to.carriage_mm - prev.carriage_mm).hypot(arc);
        prev = m.to;
    }
    assert_abs_diff_eq!(
        plan.layers[0].mark.tow_length_mm,
        laid,
        epsilon = 1e-6 * laid
    );
}

#[test]
fn tube_rules_are_enforced_with_reasons() {
    let cases: [(u32, u32, f64, f64, &str); 4] = [
        (4, 2, 720.0, 10.0, "share a factor"),
        (3, 3, 720.0, 10.0, "smaller than the pattern number"),
        (3, 1, 700.0, 10.0, "nearest valid locks"),
        (5, 1, 720.0, 10.0, "do not divide"),
    ];
    for (pattern_number, skip_index, lock_deg, lead_in_mm, expect) in cases {
        let mut job = tube_job(1);
        job.layers = vec![Layer::TubeHelical(TubeHelical {
            wind_angle_deg: 45.0,
            pattern_number,
            skip_index,
            lock_deg,
            lead_in_mm,
            lead_out_deg: 10.0,
            initial_lock: true,
            friction_lambda: 0.0,
        })];
        refused_with(&job, expect);
    }
    let mut job = tube_job(1);
    job.layers = vec![Layer::TubeHelical(TubeHelical {
        wind_angle_deg: 45.0,
        pattern_number: 3,
        skip_index: 1,
        lock_deg: 720.0,
        lead_in_mm: 2000.0,
        lead_out_deg: 10.0,
        initial_lock: true,
        friction_lambda: 0.0,
    })];
    assert!(job.check().unwrap_err().to_string().contains("lead-in"));
}

#[test]
fn estimate_counts_layers_circuits_and_time() {
    let job = seed_job(160.0, None);
    let plan = job.check().unwrap();
    let mut e = Estimate::new(plan.limits(), plan.start());
    plan.emit(&mut e).unwrap();
    assert_eq!(e.layers, 1);
    assert_eq!(e.circuits, 90);
    assert_eq!(e.moves, 1 + 90 * 82);
    // The estimate is at least the sum of the velocity-limited durations.
    let mut r = Recording::default();
    plan.emit(&mut r).unwrap();
    let nominal: f64 = r.moves.iter().map(|m| m.duration_s).sum();
    assert!(e.time_s() >= nominal, "{} < {nominal}", e.time_s());
    assert!(e.time_s() < 3.0 * nominal);
}

/// FiberPath's cone example (98 → 54 mm over 120 mm, 6 mm tow, 30° at the large end).
fn cone_job() -> Job {
    let mut job = tube_job(1);
    job.mandrel = Mandrel::Cone {
        large_radius_mm: 49.0,
        small_radius_mm: 27.0,
        length_mm: 120.0,
    };
    job.tow.band_mm = 6.0;
    job.machine.eye_radius_mm = 74.0;
    job.layers = vec![Layer::TubeHelical(TubeHelical {
        wind_angle_deg: 30.0,
        pattern_number: 3,
        skip_index: 1,
        lock_deg: 180.0,
        lead_in_mm: 5.0,
        lead_out_deg: 15.0,
        initial_lock: true,
        friction_lambda: 0.0,
    })];
    job
}

#[test]
fn cone_helical_follows_the_geodesic_and_counts_at_the_large_end() {
    let job = cone_job();
    let plan = job.check().unwrap();
    // Circuits tile the large end's parallel: ceil(2π·49·cos 30° / 6) = ceil(44.44) = 45.
    assert_eq!(plan.layers[0].mark.circuits, 45);
    assert_eq!(plan.layers[0].mark.wind_angle_deg, 30.0);
    // The pass's turn, integrated independently from the local geometry: along the generator
    // ds = dz / cos φ and r·dθ = tan α·ds with sin α = r0·sin α0 / r (Clairaut), by Simpson's
    // rule on a fine grid (the integrand is smooth: C = 24.5 < r1 = 27).
    let (r0, r1, l) = (49.0f64, 27.0f64, 120.0f64);
    let cos_phi = l / (r0 - r1).hypot(l);
    let c = r0 * 30f64.to_radians().sin();
    let f = |z: f64| {
        let r = r0 - (r0 - r1) * z / l;
        let a = (c / r).asin();
        a.tan() / (r * cos_phi)
    };
    let n = 20_000;
    let h = l / n as f64;
    let simpson: f64 = (0..=n)
        .map(|i| {
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            w * f(i as f64 * h)
        })
        .sum::<f64>()
        * h
        / 3.0;
    let pass_deg = simpson.to_degrees();
    let r = record(&job);
    let mut prev = r.moves[0].to;
    let mut pass_start: Option<Axes> = None;
    let mut passes = 0;
    let mut laid = 0.0;
    let radius = |x: f64| r0 - (r0 - r1) * (x + 60.0) / l;
    for m in &r.moves[1..] {
        assert!(
            m.to.mandrel_deg >= prev.mandrel_deg,
            "the mandrel never turns back"
        );
        assert!(m.to.carriage_mm >= -60.0 - 1e-9 && m.to.carriage_mm <= 60.0 + 1e-9);
        let dz = m.to.carriage_mm - prev.carriage_mm;
        let mid_r = radius(0.5 * (m.to.carriage_mm + prev.carriage_mm));
        let arc = if dz == 0.0 {
            radius(m.to.carriage_mm)
        } else {
            mid_r
        } * (m.to.mandrel_deg - prev.mandrel_deg).to_radians();
        laid += (dz / cos_phi).hypot(arc);
        if dz != 0.0 {
            pass_start.get_or_insert(prev);
        } else if let Some(s) = pass_start.take() {
            // A whole pass, end to end, turns the mandrel by the geodesic's turn.
            assert_abs_diff_eq!(
                (prev.carriage_mm - s.carriage_mm).abs(),
                120.0,
                epsilon = 1e-9
            );
            assert_abs_diff_eq!(prev.mandrel_deg - s.mandrel_deg, pass_deg, epsilon = 1e-6);
            // The eye lies at the local angle: 90° − 30° at the large end, 90° − asin(24.5/27)
            // at the small end.
            let small_end_eye = 90.0 - (24.5f64 / 27.0).asin().to_degrees();
            let end_eye = if prev.carriage_mm > 0.0 {
                small_end_eye
            } else {
                60.0
            };
            assert_abs_diff_eq!(prev.eye_deg.abs(), end_eye, epsilon = 1e-9);
            passes += 1;
        }
        prev = m.to;
    }
    assert_eq!(passes, 2 * 45);
    // The mark's tow: the surface length of every move (chords of the geodesic within
    // 0.01 mm, turns at the end's radius).
    assert_abs_diff_eq!(
        plan.layers[0].mark.tow_length_mm,
        laid,
        epsilon = 1e-4 * laid
    );
}

#[test]
fn cone_refusals_give_the_reason() {
    let mut job = cone_job();
    job.layers = vec![Layer::Hoop { passes: 2 }];
    refused_with(&job, "layer 1: hoop layers on a cone");
    let mut job = cone_job();
    if let Layer::TubeHelical(t) = &mut job.layers[0] {
        t.wind_angle_deg = 40.0;
    }
    let err = job.check().unwrap_err().to_string();
    assert!(err.contains("too steep") && err.contains("33.437"), "{err}");
    let mut job = cone_job();
    job.mandrel = Mandrel::Cone {
        large_radius_mm: 27.0,
        small_radius_mm: 49.0,
        length_mm: 120.0,
    };
    refused_with(&job, "reducing frustum");
    // A skip layer needs no geodesic.
    let mut job = cone_job();
    job.layers = vec![Layer::Skip { mandrel_deg: 90.0 }];
    assert!(job.check().is_ok());
}

#[test]
fn polar_layer_turns_once_per_circuit_and_keeps_the_eye_off_the_vessel() {
    for axes in [AxisSet::Four, AxisSet::Two] {
        let mut job = seed_job(84.1, None);
        job.machine.axes = axes;
        job.layers = vec![Layer::Polar {
            slip_limit: POLAR_SLIP_LIMIT,
        }];
        let plan = job.check().unwrap();
        // By hand: α = atan(21 / (42.05 + √(60² − 21²))) = 12.06429°,
        // N = ⌈2π·60·cos α / 4⌉ = ⌈92.17⌉ = 93.
        assert_eq!(plan.layers[0].mark.circuits, 93);
        assert_abs_diff_eq!(plan.layers[0].mark.wind_angle_deg, 12.06429, epsilon = 1e-5);
        let r = record(&job);
        let start = r.moves[0].to;
        let end = r.moves.last().unwrap().to;
        // 93 turns and 93 advances of 360°/93: 94 turns in all, back at the middle.
        assert_abs_diff_eq!(
            end.mandrel_deg - start.mandrel_deg,
            94.0 * 360.0,
            epsilon = 1e-6
        );
        assert_abs_diff_eq!(end.carriage_mm, 0.0, epsilon = 1e-9);
        let tan_a = 12.06429f64.to_radians().tan();
        let mut prev = start;
        let (mut far, mut near_axis) = (0.0f64, f64::MAX);
        for m in &r.moves[1..] {
            let p = m.to;
            assert!(
                p.mandrel_deg > prev.mandrel_deg,
                "the mandrel turns one way"
            );
            // Outside the vessel: farther than Rc from the axis segment |z| ≤ Lc/2.
            let beyond = (p.carriage_mm.abs() - 42.05).max(0.0);
            assert!(p.cross_feed_mm.hypot(beyond) > 60.0, "{p:?}");
            far = far.max(p.carriage_mm.abs());
            near_axis = near_axis.min(p.cross_feed_mm);
            if axes == AxisSet::Two {
                assert_abs_diff_eq!(p.cross_feed_mm, 90.0, epsilon = 1e-9);
                assert_eq!(p.eye_deg, 0.0);
            }
            prev = p;
        }
        if axes == AxisSet::Two {
            // The eye keeps Re: the carriage swings to Re / tan α = 90 / 0.213728 = 421.1 mm.
            assert_abs_diff_eq!(far, 90.0 / tan_a, epsilon = 1e-3);
        } else {
            // With cross-feed the eye passes the pole at rp + (Re − Rc)·sin α, past it by
            // (Re − Rc)·cos α.
            let a = 12.06429f64.to_radians();
            assert_abs_diff_eq!(near_axis, 21.0 + 30.0 * a.sin(), epsilon = 1e-3);
            assert_abs_diff_eq!(far, 98.25498 + 30.0 * a.cos(), epsilon = 1e-3);
        }
    }
}

/// FiberPath's nose example: a von Kármán ogive of base 98 mm over 300 mm, 7 mm tow, 30° at the
/// base, with friction ratio `lambda`.
fn nose_job(lambda: f64) -> Job {
    let mut job = cone_job();
    job.mandrel = Mandrel::VonKarman {
        base_radius_mm: 49.0,
        length_mm: 300.0,
    };
    job.tow.band_mm = 7.0;
    if let Layer::TubeHelical(t) = &mut job.layers[0] {
        t.friction_lambda = lambda;
    }
    job
}

/// The Haack radius written out (x from the tip, φ = acos(1 − 2x/L)).
fn haack(z: f64) -> f64 {
    let phi = (1.0 - 2.0 * (300.0 - z) / 300.0).acos();
    49.0 / PI.sqrt() * (phi - (2.0 * phi).sin() / 2.0).sqrt()
}

/// Walks a one-layer nose plan's moves: returns each circuit's (mandrel angle at its start,
/// outward turn, return turn, farthest carriage) and the surface length of every move.
/// Every circuit of [`nose_circuits`] starts on its own slot of 360°/n (n circuits), whatever
/// the order in which the pattern visits them.
fn assert_on_their_own_slots(circuits: &[(f64, f64, f64, f64)]) {
    let n = circuits.len();
    let mut slots: Vec<f64> = circuits
        .iter()
        .map(|c| (c.0 - circuits[0].0).rem_euclid(360.0))
        .collect();
    slots.sort_by(f64::total_cmp);
    for (k, s) in slots.iter().enumerate() {
        assert_abs_diff_eq!(*s, k as f64 * 360.0 / n as f64, epsilon = 1e-6);
    }
}

fn nose_circuits(job: &Job) -> (Vec<(f64, f64, f64, f64)>, f64) {
    let r = record(job);
    let mut prev = r.moves[0].to;
    let mut out = Vec::new();
    let mut laid = 0.0;
    // (start angle, angle at the far end, far carriage) of the circuit under way.
    let mut open: Option<(f64, f64, f64)> = None;
    for m in &r.moves[1..] {
        let to = m.to;
        assert!(
            to.mandrel_deg >= prev.mandrel_deg,
            "the mandrel never turns back"
        );
        let (z0, z1) = (prev.carriage_mm + 150.0, to.carriage_mm + 150.0);
        assert!((-1e-9..=300.0).contains(&z1));
        let zm = 0.5 * (z0 + z1);
        let h = 1e-6;
        let slope = (haack((zm + h).min(300.0)) - haack((zm - h).max(0.0))) / (2.0 * h);
        laid += ((z1 - z0) * (1.0 + slope * slope).sqrt())
            .hypot(haack(zm) * (to.mandrel_deg - prev.mandrel_deg).to_radians());
        if z1 > z0 {
            let o = open.get_or_insert((prev.mandrel_deg, 0.0, 0.0));
            o.1 = to.mandrel_deg;
            o.2 = z1;
        } else if z1 < z0 && z1 == 0.0 {
            let (start, far, z) = open.take().unwrap();
            out.push((start, far - start, to.mandrel_deg - far, z));
        }
        prev = to;
    }
    (out, laid)
}

#[test]
fn nose_helical_runs_from_the_base_to_the_geodesic_turnaround_and_back() {
    let job = nose_job(0.0);
    let plan = job.check().unwrap();
    // Circuits tile the base's parallel: ⌈2π·49·cos 30° / 7⌉ = ⌈38.09⌉ = 39.
    assert_eq!(plan.layers[0].mark.circuits, 39);
    assert_eq!(plan.layers[0].mark.wind_angle_deg, 30.0);
    let ogive = nose::VonKarman {
        base_radius_mm: 49.0,
        length_mm: 300.0,
    };
    let (zt, theta, length) = nose::tests::clairaut_quadrature(&ogive, 30.0);
    // The turnaround is where the Haack radius is C = 49·sin 30° = 24.5 mm.
    assert_abs_diff_eq!(haack(zt), 24.5, epsilon = 1e-9);
    let (circuits, laid) = nose_circuits(&job);
    assert_eq!(circuits.len(), 39);
    for &(_, out, back, far) in &circuits {
        assert_abs_diff_eq!(far, zt, epsilon = 1e-6);
        assert_abs_diff_eq!(out, theta.to_degrees(), epsilon = 1e-5);
        assert_abs_diff_eq!(back, theta.to_degrees(), epsilon = 1e-5);
    }
    // Every circuit starts on its own slot of 360°/39.
    assert_on_their_own_slots(&circuits);
    // The mark's tow: the passes' geodesic length and the turns at the base, against the
    // surface length of the moves (chords within 0.01 mm).
    let mark = plan.layers[0].mark.tow_length_mm;
    assert!(mark > 2.0 * 39.0 * length);
    assert_abs_diff_eq!(mark, laid, epsilon = 1e-4 * laid);
}

#[test]
fn nose_friction_lays_deeper_and_keeps_the_pattern() {
    let geodesic = nose_circuits(&nose_job(0.0)).0;
    let (circuits, laid) = nose_circuits(&nose_job(0.15));
    assert_eq!(circuits.len(), 39);
    let far = circuits[0].3;
    // Deeper than the geodesic's turnaround, on a radius where the meridian is steeper than λ.
    assert!(far > geodesic[0].3 + 50.0, "{far}");
    let h = 1e-6;
    assert!((haack(far + h) - haack(far - h)).abs() / (2.0 * h) > 0.15);
    for c in &circuits {
        assert_abs_diff_eq!(c.1, c.2, epsilon = 1e-9);
        assert_abs_diff_eq!(c.3, far, epsilon = 1e-9);
    }
    assert_on_their_own_slots(&circuits);
    let plan = nose_job(0.15).check().unwrap();
    assert_abs_diff_eq!(
        plan.layers[0].mark.tow_length_mm,
        laid,
        epsilon = 1e-4 * laid
    );
}

#[test]
fn nose_refusals_give_the_reason() {
    let mut job = nose_job(0.0);
    job.layers = vec![Layer::Hoop { passes: 2 }];
    refused_with(&job, "layer 1: hoop layers on a nose profile");
    let mut job = nose_job(0.0);
    job.layers.push(Layer::Helical(PatternRequest::default()));
    refused_with(&job, "layer 2: a geodesic dome layer needs a vessel");
    for (lambda, expect) in [
        (-0.1, "frictionLambda = -0.1 must be ≥ 0"),
        (f64::NAN, "frictionLambda = NaN must be ≥ 0"),
        (
            0.21,
            "frictionLambda 0.21 exceeds the machine slip limit 0.2",
        ),
    ] {
        refused_with(&nose_job(lambda), expect);
    }
    assert!(nose_job(NOSE_SLIP_LIMIT).check().is_ok());
    // Friction on a cone or a tube is refused: they are wound on their geodesics.
    let mut cone = cone_job();
    if let Layer::TubeHelical(t) = &mut cone.layers[0] {
        t.friction_lambda = 0.1;
    }
    refused_with(&cone, "frictionLambda = 0.1: a cylinder or cone");
    // Build-up would wind on an offset of the ogive: refused on the second layer.
    let mut job = nose_job(0.0);
    job.build_up = true;
    job.layers.push(job.layers[0]);
    refused_with(&job, "layer 2: layer build-up on a nose profile");
    // A path that reaches the tip: a shallow geodesic, C = 49·sin 0.4° < 1 % of 49 mm.
    let mut job = nose_job(0.0);
    if let Layer::TubeHelical(t) = &mut job.layers[0] {
        t.wind_angle_deg = 1.0;
        t.lead_in_mm = 1.0;
    }
    // Friction near the tip: at 1° with λ = 0.05 the path passes C = 49·sin 1° = 0.855 mm and
    // reaches 1 % of the base radius without turning; with λ = 0.2 friction first turns the
    // fibre onto the meridian (the meridian's curvature is large near the base).
    let cases = [
        (
            0.05,
            "wind angle 1° with frictionLambda 0.05: the path reaches the tip (radius 0.49",
        ),
        (
            0.2,
            "wind angle 1° with frictionLambda 0.2: friction turns the fibre onto the meridian",
        ),
    ];
    for (lambda, expect) in cases {
        if let Layer::TubeHelical(t) = &mut job.layers[0] {
            t.friction_lambda = lambda;
        }
        let err = refused_with(&job, expect);
        if lambda == 0.05 {
            assert!(
                err.contains("above 0.4900 mm (1% of") && err.contains("sin α, 0.8552 mm"),
                "{err}"
            );
        }
    }
    // A nose 1 mm across and a kilometre long: steps of r/200 would be ~10⁸; refused at the cap
    // (bounded time and memory).
    let mut job = nose_job(0.0);
    job.mandrel = Mandrel::VonKarman {
        base_radius_mm: 0.5,
        length_mm: 1e6,
    };
    refused_with(
        &job,
        "wind angle 30° with frictionLambda 0: the pass needs more than 400000",
    );
    // No usable pass: 89° turns around inside the lead-in.
    let mut job = nose_job(0.0);
    if let Layer::TubeHelical(t) = &mut job.layers[0] {
        t.wind_angle_deg = 89.0;
    }
    let err = job.check().unwrap_err().to_string();
    assert!(
        err.contains("wind angle 89° has no usable pass") && err.contains("86.5437°"),
        "{err}"
    );
}

#[test]
fn nose_base_turn_is_at_least_the_lead_out() {
    // Lock 120° and skip 2 of 3 slots: the circuit advances by 2·lock = 240° (mod 360°) with the
    // two passes' turn 2·θt; (240° − 2·θt) mod 360° = 151.77° is below the 160° lead-out, so the
    // base turn is a whole turn more.
    let mut job = nose_job(0.0);
    if let Layer::TubeHelical(t) = &mut job.layers[0] {
        t.lock_deg = 120.0;
        t.lead_out_deg = 160.0;
        t.skip_index = 2;
    }
    let ogive = nose::VonKarman {
        base_radius_mm: 49.0,
        length_mm: 300.0,
    };
    let theta = nose::tests::clairaut_quadrature(&ogive, 30.0)
        .1
        .to_degrees();
    let base_turn = (240.0 - 2.0 * theta).rem_euclid(360.0) + 360.0;
    assert!(base_turn > 160.0 && base_turn < 160.0 + 360.0);
    let (circuits, laid) = nose_circuits(&job);
    assert_eq!(circuits.len(), 39);
    for (k, w) in circuits.windows(2).enumerate() {
        let gap = w[1].0 - (w[0].0 + w[0].1 + w[0].2);
        // The skip (2 slots of 120°) after each circuit, a step of 360°/39 after each pattern.
        let step = if k % 3 == 2 { 360.0 / 39.0 } else { 0.0 };
        assert_abs_diff_eq!(gap, base_turn + 240.0 + step, epsilon = 1e-5);
    }
    assert_on_their_own_slots(&circuits);
    let plan = job.check().unwrap();
    assert_abs_diff_eq!(
        plan.layers[0].mark.tow_length_mm,
        laid,
        epsilon = 1e-4 * laid
    );
}

#[test]
fn nose_eye_swings_over_the_lead_in_and_lies_at_the_local_angle() {
    // The eye at 90° − α(z), α from Clairaut (sin α = 24.5 / r(z)); over the lead-in it
    // swings up in proportion to the carriage's travel; on the way back it lies on the other side.
    // A 100 mm lead-in, so that stations fall inside it.
    let mut job = nose_job(0.0);
    if let Layer::TubeHelical(t) = &mut job.layers[0] {
        t.lead_in_mm = 100.0;
    }
    let r = record(&job);
    let mut prev = r.moves[0].to;
    let (mut inside, mut outward, mut back) = (0, 0, 0);
    for m in &r.moves[1..] {
        let to = m.to;
        let z = to.carriage_mm + 150.0;
        let lay = 90.0 - (24.5 / haack(z)).min(1.0).asin().to_degrees();
        if to.carriage_mm > prev.carriage_mm {
            let swing = (z / 100.0).min(1.0);
            assert_abs_diff_eq!(to.eye_deg, swing * lay, epsilon = 1e-5);
            if z < 100.0 - 1e-9 {
                inside += 1;
            } else {
                outward += 1;
            }
        } else if to.carriage_mm < prev.carriage_mm {
            assert_abs_diff_eq!(to.eye_deg, -lay, epsilon = 1e-5);
            back += 1;
        } else {
            // Every turn with the carriage still is at the base, the eye back at 0.
            assert_eq!(to.carriage_mm, -150.0);
            assert_eq!(to.eye_deg, 0.0);
        }
        prev = to;
    }
    assert!(
        inside > 39 * 10 && outward > 39 * 10 && back > 39 * 50,
        "{inside} {outward} {back}"
    );
}

/// The eye's lie on a hoop pass at one band per turn: the fibre advances one band b along the
/// axis per circumference 2πR, so it leans atan(b / 2πR) off the circumferential direction.
fn hoop_eye_deg(radius_mm: f64, band_mm: f64) -> f64 {
    (band_mm / (TAU * radius_mm)).atan().to_degrees()
}

/// Layer `k`'s moves (k ≥ 1) and where the layer before left the axes.
fn layer_moves(r: &Recording, k: usize) -> (Axes, &[Move]) {
    let start = r.layer_starts[k];
    let end = r.layer_starts.get(k + 1).copied().unwrap_or(r.moves.len());
    (r.moves[start - 1].to, &r.moves[start..end])
}

/// A feed to `want` (mandrel, carriage, cross-feed, eye).
fn assert_feed_to(m: &Move, want: [f64; 4]) {
    assert_move_to(m, MoveKind::Feed, want);
}

/// A move of `kind` to `want`, the mandrel to 10⁻⁶ ° (it may have turned through 10⁵ ° by
/// then), the other axes to 10⁻⁹.
fn assert_move_to(m: &Move, kind: MoveKind, want: [f64; 4]) {
    assert_eq!(m.kind, kind, "{m:?}");
    let got = m.to.to_array();
    assert!(
        (got[0] - want[0]).abs() <= 1e-6,
        "mandrel: {m:?} vs {want:?}"
    );
    for axis in 1..4 {
        assert!(
            (got[axis] - want[axis]).abs() <= 1e-9,
            "axis {axis}: {m:?} vs {want:?}"
        );
    }
}

#[test]
fn hoop_starts_where_the_layer_before_ended_without_a_transition_turn() {
    // Tube R 35 mm × 1460 mm, 6.5 mm band, the eye 80 mm from the axis. A tube layer ends at
    // the near end (−730 mm), a one-pass hoop after it at the far end (+730 mm), then a
    // two-pass hoop. Each hoop starts at the end the carriage is at: no travel, so no turn.
    let mut job = tube_job(1);
    job.layers.push(Layer::Hoop { passes: 1 });
    job.layers.push(Layer::Hoop { passes: 2 });
    let r = record(&job);
    let e = hoop_eye_deg(35.0, 6.5);
    // 1460 / 6.5 turns per pass.
    let pass = 1460.0 / 6.5 * 360.0;

    let (before, m) = layer_moves(&r, 1);
    assert_eq!((before.carriage_mm, before.eye_deg), (-730.0, 0.0));
    assert_eq!(m.len(), 2);
    // The approach moves the eye alone: to +e, the pass runs towards +730.
    let a = before.mandrel_deg;
    assert_feed_to(&m[0], [a, -730.0, 80.0, e]);
    assert_feed_to(&m[1], [a + pass, 730.0, 80.0, e]);

    let (before, m) = layer_moves(&r, 2);
    assert_eq!(before.carriage_mm, 730.0);
    let a = before.mandrel_deg;
    assert_eq!(m.len(), 4);
    // From the far end: the first pass runs towards −730, the eye at −e.
    assert_feed_to(&m[0], [a, 730.0, 80.0, -e]);
    assert_feed_to(&m[1], [a + pass, -730.0, 80.0, -e]);
    // Between the passes the eye swings over to +e with the mandrel and carriage still.
    assert_feed_to(&m[2], [a + pass, -730.0, 80.0, e]);
    assert_feed_to(&m[3], [a + 2.0 * pass, 730.0, 80.0, e]);
}

#[test]
fn hoop_after_a_layer_ending_off_the_cylinder_end_turns_the_mandrel_once() {
    // Seed 002's vessel (Rc 60, Lc 84.1, rp 21, 4 mm band, Re 90), no build-up. A dome layer
    // ends at the near polar opening, √(60² − 21²) = 56.20498 mm beyond the cylinder's end; a
    // polar layer ends at the cylinder's middle. A hoop after either starts at −42.05 mm (the
    // nearer end; from the middle both are as near and the hoop runs forward), a carriage travel
    // of more than one band: the approach turns the mandrel by one full turn.
    let e = hoop_eye_deg(60.0, 4.0);
    let pass = 84.1 / 4.0 * 360.0;
    for (first, ended_at) in [
        (Layer::Helical(PatternRequest::default()), -98.25498),
        (
            Layer::Polar {
                slip_limit: POLAR_SLIP_LIMIT,
            },
            0.0,
        ),
    ] {
        let mut job = seed_job(84.1, None);
        job.build_up = false;
        job.layers = vec![first, Layer::Hoop { passes: 1 }];
        let r = record(&job);
        let (before, m) = layer_moves(&r, 1);
        assert_abs_diff_eq!(before.carriage_mm, ended_at, epsilon = 1e-5);
        assert_eq!(m.len(), 2);
        let a = before.mandrel_deg;
        assert_feed_to(&m[0], [a + 360.0, -42.05, 90.0, e]);
        assert_feed_to(&m[1], [a + 360.0 + pass, 42.05, 90.0, e]);
    }
}

#[test]
fn transition_turn_only_when_the_carriage_travels_more_than_a_band() {
    // Tube R 35 mm, 4 mm band, eye at 80 mm. A skip first turns the mandrel 90° with the
    // carriage where every plan starts, the middle; the hoop after it starts at −L/2: a travel of
    // 3.75, 4 (one band, not more) and 4.25 mm for L = 7.5, 8 and 8.5 mm.
    let e = hoop_eye_deg(35.0, 4.0);
    for (length, turn) in [(7.5, 0.0), (8.0, 0.0), (8.5, 360.0)] {
        let mut job = tube_job(1);
        job.mandrel = Mandrel::Tube {
            radius_mm: 35.0,
            length_mm: length,
        };
        job.tow.band_mm = 4.0;
        job.layers = vec![Layer::Skip { mandrel_deg: 90.0 }, Layer::Hoop { passes: 1 }];
        let r = record(&job);
        assert_eq!(r.layer_starts, [0, 1]);
        assert_feed_to(&r.moves[0], [90.0, 0.0, 0.0, 0.0]);
        let (_, m) = layer_moves(&r, 1);
        assert_eq!(m.len(), 2, "L = {length}");
        assert_feed_to(&m[0], [90.0 + turn, -length / 2.0, 80.0, e]);
        assert_feed_to(
            &m[1],
            [90.0 + turn + length / 4.0 * 360.0, length / 2.0, 80.0, e],
        );
    }
}

#[test]
fn one_pass_hoops_in_a_row_alternate_ends_at_any_length() {
    // Three one-pass hoops on a tube (R 35 mm, eye at 80 mm), 0.8 mm long with a 0.2 mm band
    // and 1460 mm long with a 6.5 mm band: each starts at the end the one before reached
    // (+L/2, then −L/2), with no transition turn, the eye on the side the pass runs to.
    for (length, band) in [(0.8, 0.2), (1460.0, 6.5)] {
        let mut job = tube_job(1);
        job.mandrel = Mandrel::Tube {
            radius_mm: 35.0,
            length_mm: length,
        };
        job.tow.band_mm = band;
        job.layers = vec![Layer::Hoop { passes: 1 }; 3];
        let r = record(&job);
        let (h, e, pass) = (
            length / 2.0,
            hoop_eye_deg(35.0, band),
            length / band * 360.0,
        );
        assert_eq!(r.layer_starts, [0, 2, 4], "L = {length}");
        assert_move_to(&r.moves[0], MoveKind::Rapid, [0.0, -h, 80.0, e]);
        assert_feed_to(&r.moves[1], [pass, h, 80.0, e]);
        assert_feed_to(&r.moves[2], [pass, h, 80.0, -e]);
        assert_feed_to(&r.moves[3], [2.0 * pass, -h, 80.0, -e]);
        assert_feed_to(&r.moves[4], [2.0 * pass, -h, 80.0, e]);
        assert_feed_to(&r.moves[5], [3.0 * pass, h, 80.0, e]);
        assert_eq!(r.moves.len(), 6);
    }
}
