use super::*;
use paths::motion::{AxisLimit, Limits};
use paths::pattern::PatternRequest;
use paths::vessel::{Job, Layer, Machine, Mandrel, Tow, TubeHelical};

fn limits() -> Limits {
    let l = AxisLimit {
        velocity: 100.0,
        acceleration: 1000.0,
    };
    Limits {
        axes: [
            AxisLimit {
                velocity: 720.0,
                acceleration: 2000.0,
            },
            l,
            l,
            AxisLimit {
                velocity: 360.0,
                acceleration: 2000.0,
            },
        ],
        junction_deviation: 0.01,
    }
}

fn vessel(axes: AxisSet) -> Job {
    Job {
        mandrel: Mandrel::Vessel {
            cylinder_radius_mm: 60.0,
            cylinder_length_mm: 160.0,
            polar_radius_mm: 21.0,
        },
        tow: Tow {
            band_mm: 4.0,
            thickness_mm: 0.2,
        },
        machine: Machine {
            axes,
            eye_radius_mm: 90.0,
            limits: limits(),
            dome_steps: 10,
        },
        layers: vec![
            Layer::Helical(PatternRequest::default()),
            Layer::Hoop { passes: 2 },
            Layer::Skip { mandrel_deg: 45.0 },
            Layer::Helical(PatternRequest::default()),
        ],
        build_up: true,
    }
}

fn tube() -> Job {
    Job {
        mandrel: Mandrel::Tube {
            radius_mm: 35.0,
            length_mm: 500.0,
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
            Layer::Hoop { passes: 2 },
            Layer::TubeHelical(TubeHelical {
                wind_angle_deg: 45.0,
                pattern_number: 3,
                skip_index: 1,
                lock_deg: 720.0,
                lead_in_mm: 10.0,
                lead_out_deg: 10.0,
                initial_lock: true,
                friction_lambda: 0.0,
            }),
        ],
        build_up: false,
    }
}

fn write(job: &Job, dialect: Dialect) -> (Recording, String) {
    let plan = job.check().unwrap();
    let mut rec = Recording::default();
    plan.emit(&mut rec).unwrap();
    let mut w = Writer::new(
        Vec::new(),
        dialect,
        job.machine.axes,
        &Header {
            title: "test".into(),
            parameters: None,
        },
    )
    .unwrap();
    plan.emit(&mut w).unwrap();
    let text = String::from_utf8(w.finish().unwrap().0).unwrap();
    (rec, text)
}

/// The plan's moves as they can be written: targets rounded to the LSB, moves that round to no
/// motion merged into nothing, rapids as feeds where the dialect has no rapid.
fn expected(rec: &Recording, dialect: Dialect, axes: AxisSet) -> (Vec<Move>, Vec<usize>) {
    let used = [true, true, axes.cross_feed(), axes.eye_rotation()];
    let mut out = Vec::new();
    let mut starts = Vec::new();
    let mut last = [0i64; 4];
    let mut layer = 0;
    for (i, m) in rec.moves.iter().enumerate() {
        while layer < rec.layer_starts.len() && rec.layer_starts[layer] == i {
            starts.push(out.len());
            layer += 1;
        }
        let q = m.to.to_array().map(quantise);
        let q: [i64; 4] = std::array::from_fn(|k| if used[k] { q[k] } else { 0 });
        if q == last {
            continue;
        }
        last = q;
        let mut m = *m;
        m.to = Axes::from_array(q.map(|v| v as f64 * UNITS_PER_LSB));
        if dialect == Dialect::FwCnc {
            m.kind = MoveKind::Feed;
            m.duration_s = 0.0;
        }
        out.push(m);
    }
    while layer < rec.layer_starts.len() {
        starts.push(out.len());
        layer += 1;
    }
    (out, starts)
}

fn assert_round_trip(job: &Job, dialect: Dialect) {
    let (rec, text) = write(job, dialect);
    let back = read(&text, dialect).unwrap_or_else(|e| panic!("{dialect}: {e}"));
    let (want, starts) = expected(&rec, dialect, job.machine.axes);
    assert_eq!(back.moves.len(), want.len(), "{dialect}: move count");
    for (i, (got, want)) in back.moves.iter().zip(&want).enumerate() {
        assert_eq!(got.kind, want.kind, "{dialect} move {i}");
        for (g, w) in got.to.to_array().iter().zip(want.to.to_array()) {
            assert!(
                (g - w).abs() < 1e-6,
                "{dialect} move {i}: {got:?} vs {want:?}"
            );
        }
        let tolerance = 1e-5 * want.duration_s.max(1e-3);
        assert!(
            (got.duration_s - want.duration_s).abs() <= tolerance
                // A move whose words round shorter or longer than planned keeps its feed.
                || dialect == Dialect::Mach3
                || dialect == Dialect::Marlin,
            "{dialect} move {i}: {} s vs {} s",
            got.duration_s,
            want.duration_s
        );
    }
    assert_eq!(back.layer_starts, starts, "{dialect}: layer boundaries");
    let kinds: Vec<_> = back
        .layers
        .iter()
        .map(|l| (l.number, l.kind, l.circuits))
        .collect();
    let planned: Vec<_> = rec
        .layers
        .iter()
        .map(|l| (l.number, l.kind, l.circuits))
        .collect();
    assert_eq!(kinds, planned, "{dialect}: layers");
}

#[test]
fn every_dialect_reads_back_to_the_same_motion() {
    for dialect in Dialect::ALL {
        let axes = if dialect == Dialect::FwCnc {
            AxisSet::Three
        } else {
            AxisSet::Four
        };
        assert_round_trip(&vessel(axes), dialect);
        assert_round_trip(&vessel(AxisSet::Two), dialect);
        if dialect != Dialect::FwCnc {
            assert_round_trip(&tube(), dialect);
        }
    }
}

#[test]
fn feed_dialects_keep_durations_from_their_feed_words() {
    // Mach3 and Marlin state a feed per length: the duration comes back from the rounded words
    // within the feed's six digits and the rounding of short words.
    for dialect in [Dialect::Mach3, Dialect::Marlin] {
        let (rec, text) = write(&vessel(AxisSet::Four), dialect);
        let back = read(&text, dialect).unwrap();
        let planned: f64 = rec.moves.iter().map(|m| m.duration_s).sum();
        let read: f64 = back.moves.iter().map(|m| m.duration_s).sum();
        assert!(
            (planned - read).abs() < 1e-3 * planned,
            "{dialect}: {planned} vs {read}"
        );
    }
}

#[test]
fn g0_only_for_the_first_positioning_and_g1_has_a_feed() {
    for dialect in [
        Dialect::Mach3,
        Dialect::Grbl,
        Dialect::LinuxCnc,
        Dialect::Marlin,
        Dialect::Fanuc,
    ] {
        let (_, text) = write(&vessel(AxisSet::Four), dialect);
        let g0 = text.lines().filter(|l| l.starts_with("G0 ")).count();
        assert_eq!(g0, 1, "{dialect}");
        for l in text.lines().filter(|l| l.starts_with("G1 ")) {
            assert!(l.contains(" F"), "{dialect}: {l}");
        }
    }
}

#[test]
fn mach3_stroke_is_the_appendix_text() {
    let mut job = vessel(AxisSet::Four);
    job.mandrel = Mandrel::Vessel {
        cylinder_radius_mm: 60.0,
        cylinder_length_mm: 84.1,
        polar_radius_mm: 21.0,
    };
    let (_, text) = write(&job, Dialect::Mach3);
    let lines: Vec<&str> = text.lines().collect();
    let g91 = lines.iter().position(|l| *l == "G91").unwrap();
    // Seed 002 Appendix A, O0004: the first move and the cylinder.
    assert!(lines[g91 + 1].starts_with("G1 X2.283 Y4.731 Z3.535 A11.042 F"));
    assert!(
        lines[g91 + 21].starts_with("G1 X30.006 Y84.1 F"),
        "{}",
        lines[g91 + 21]
    );
}

#[test]
fn grbl_rezeroes_the_mandrel_by_whole_turns() {
    let (rec, text) = write(&vessel(AxisSet::Four), Dialect::Grbl);
    assert!(rec.moves.last().unwrap().to.mandrel_deg > 40_000.0);
    let mut rezero = 0;
    for l in text.lines() {
        for w in l.split(' ').filter(|w| w.starts_with('A')) {
            let v: f64 = w[1..].parse().unwrap();
            assert!(v.abs() <= REZERO_BEYOND_DEG + 40.0 * 360.0, "{l}");
        }
        rezero += usize::from(l.starts_with("G92 A"));
    }
    assert!(rezero > 5);
    // LinuxCNC keeps the unwrapped angle.
    let (_, text) = write(&vessel(AxisSet::Four), Dialect::LinuxCnc);
    assert!(!text.contains("G92"));
}

#[test]
fn fw_cnc_refuses_an_eye_axis_and_writes_fig_9_1_blocks() {
    let err = Writer::new(
        Vec::new(),
        Dialect::FwCnc,
        AxisSet::Four,
        &Header::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("no eye rotation axis"), "{err}");
    let (_, text) = write(&vessel(AxisSet::Three), Dialect::FwCnc);
    assert!(text.starts_with("%\nO 1;\n"));
    assert!(text.ends_with("M30;\n%\n"));
    assert!(
        text.lines()
            .filter(|l| l.starts_with("G01 "))
            .all(|l| l.ends_with(';'))
    );
}

#[test]
fn numbers_are_written_exactly() {
    let mut out = Vec::new();
    for v in [0, 1, -1, 1500, -30006, 84100, 123_456_789] {
        push_fixed(&mut out, v);
        out.push(b' ');
    }
    assert_eq!(
        String::from_utf8(out).unwrap(),
        "0 0.001 -0.001 1.5 -30.006 84.1 123456.789 "
    );
    let mut f = Vec::new();
    push_feed(&mut f, 6000.0);
    f.push(b' ');
    push_feed(&mut f, 1.0 / 3.0);
    assert_eq!(String::from_utf8(f).unwrap(), "6000 0.333333");
}

#[test]
fn reader_rejects_what_it_did_not_write_with_line_and_column() {
    let e = read("G1 X1 F10\nG2 X3 Y4\n", Dialect::Grbl)
        .unwrap_err()
        .to_string();
    assert_eq!(e, "2:1: G2 is not written in grbl");
    let e = read("G1 Q5\n", Dialect::Grbl).unwrap_err().to_string();
    assert_eq!(e, "1:4: axis Q is not written in grbl");
    let e = read("G1 X\n", Dialect::Grbl).unwrap_err().to_string();
    assert_eq!(e, "1:4: word X has no number");
    let e = read("(open\n", Dialect::Mach3).unwrap_err().to_string();
    assert_eq!(e, "1:1: comment without `)`");
}

#[test]
fn dialect_names_round_trip() {
    for d in Dialect::ALL {
        assert_eq!(Dialect::from_name(d.name()), Some(d));
        assert!(!d.extension().is_empty());
    }
    assert_eq!(Dialect::from_name("haas"), None);
}
