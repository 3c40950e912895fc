//! Mesh mandrels through the `windcell` command line: `geodesic`, `triasym` and `plan` with a
//! mesh mandrel, and the errors a bad mesh file gives.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::{example, stderr, windcell, windcell_json};

/// `windcell plan JOB -o OUT EXTRA…`.
fn plan(job: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["plan", job.to_str().unwrap(), "-o", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    windcell(&args)
}

/// `windcell geodesic MESH --start START --heading HEADING EXTRA…`.
fn geodesic(mesh: &Path, start: &str, heading: &str, extra: &[&str]) -> Output {
    let mut args = vec![
        "geodesic",
        mesh.to_str().unwrap(),
        "--start",
        start,
        "--heading",
        heading,
    ];
    args.extend_from_slice(extra);
    windcell(&args)
}

/// A point of `examples/sbend.stl`: the spine's offset at 200 mm is −18 mm, so (−18, 28.5, 200)
/// mm lies on the surface at 90° around.
const SBEND_START: &str = "-18,28.5,200";

/// `geodesic` on `examples/sbend.stl` from [`SBEND_START`] with `--json`: the report.
fn sbend_geodesic_json(heading: &str, extra: &[&str]) -> serde_json::Value {
    let r = geodesic(
        &example("sbend.stl"),
        SBEND_START,
        heading,
        &[extra, &["--json"]].concat(),
    );
    assert!(r.status.success(), "{}", stderr(&r));
    serde_json::from_slice(&r.stdout).unwrap()
}

/// A refusal as bad input: exit code 2, and standard error names `what`.
fn refused_naming(r: &Output, what: &str) {
    assert_eq!(r.status.code(), Some(2), "{}", stderr(r));
    assert!(stderr(r).contains(what), "{} lacks {what}", stderr(r));
}

/// `windcell plan JOB -o OUT --json`: each path's total mandrel steps.
fn planned_steps(job: &Path, out: &Path) -> Vec<i64> {
    let r = plan(job, out, &["--json"]);
    assert!(r.status.success(), "{}: {}", job.display(), stderr(&r));
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    v["paths"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["total_steps"].as_i64().unwrap())
        .collect()
}

#[test]
fn triasym_reproduces_the_shipped_sbend_stl() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sbend.stl");
    let r = windcell(&[
        "triasym",
        example("sbend.toml").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    assert_eq!(
        std::fs::read(&out).unwrap(),
        std::fs::read(example("sbend.stl")).unwrap()
    );
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&out).unwrap().permissions().mode();
        assert_ne!(mode & 0o044, 0, "readable by others: {mode:o}");
    }
}

#[test]
fn geodesic_prints_points_and_faces_and_stops_at_the_end_cap() {
    // Spine offset at 200 mm is −18 mm: (−18, 28.5, 200) lies on the surface at 90° around.
    let v = sbend_geodesic_json("45", &[]);
    let points = v["points_mm"].as_array().unwrap();
    assert_eq!(points.len(), v["faces"].as_array().unwrap().len());
    assert!(points.len() > 100);
    assert_eq!(v["stop"], "boundary");
    let last_z = points.last().unwrap()[2].as_f64().unwrap();
    assert!(last_z > 340.0, "ends on the top rim, z = {last_z}");
    // Text output, a height limit and a slip ratio within the friction.
    let r = geodesic(
        &example("sbend.stl"),
        SBEND_START,
        "-30",
        &["--heights", "150,250", "--lambda", "0.1", "--mu", "0.2"],
    );
    assert!(r.status.success(), "{}", stderr(&r));
    let text = String::from_utf8(r.stdout).unwrap();
    assert!(
        text.trim_end()
            .ends_with("stopped at the edge of the --heights range"),
        "{text}"
    );
    // Smoothed and cut into equal lengths on the surface.
    let v = sbend_geodesic_json("45", &["--segments", "20"]);
    let seg = &v["segments"];
    assert_eq!(seg["points_mm"].as_array().unwrap().len(), 21);
    let dev = seg["max_deviation_mm"].as_f64().unwrap();
    assert!(dev < 0.05, "{dev}");
}

#[test]
fn bad_input_exits_2_naming_the_file_and_line_or_triangle() {
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("bad.stl");
    std::fs::write(
        &stl,
        "solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 oops\n",
    )
    .unwrap();
    let obj = dir.path().join("bad.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 7\n").unwrap();
    let open = dir.path().join("open.obj");
    std::fs::write(
        &open,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 2 2\nf 1 2 3\nf 1 2 4\n",
    )
    .unwrap();
    let empty = dir.path().join("empty.stl");
    std::fs::write(&empty, "").unwrap();
    let cases: [(&Path, &str); 4] = [
        (&stl, "bad.stl:5:15: `oops` is not a number"),
        (&obj, "bad.obj:5:7: `7`: vertex 7 does not exist"),
        (&open, "open.obj:6:1: triangle 1: inconsistent orientation"),
        (&empty, "empty.stl: byte 0: the file is empty"),
    ];
    for (file, message) in cases {
        let r = geodesic(file, "0,0,0", "0", &[]);
        refused_naming(&r, message);
        assert!(r.stdout.is_empty());
    }
    // Slip beyond the friction, before anything is read.
    let r = geodesic(
        &example("sbend.stl"),
        SBEND_START,
        "45",
        &["--lambda", "0.4", "--mu", "0.3"],
    );
    refused_naming(&r, "exceeds the friction coefficient");
    // A mesh job whose mesh is bad writes nothing.
    let job = std::fs::read_to_string(example("sbend-mesh.toml"))
        .unwrap()
        .replace("mesh = \"sbend.stl\"", "mesh = \"bad.stl\"");
    let job_file = dir.path().join("job.toml");
    std::fs::write(&job_file, job).unwrap();
    let out = dir.path().join("out");
    refused_naming(&plan(&job_file, &out, &[]), "bad.stl:5:15: ");
    assert!(!out.exists());
}

/// The S-bend tube job cut square at its ends, like the TRIASYM mesh's end caps, as `sbend.toml`
/// in `dir`.
fn square_ended_sbend(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(example("sbend.toml"))
        .unwrap()
        .replacen("kind = \"tube\"", "kind = \"tube\"\nends = \"square\"", 1);
    let file = dir.join("sbend.toml");
    std::fs::write(&file, text).unwrap();
    file
}

#[test]
fn plan_runs_the_tool_step_from_the_sbend_stl_like_the_analytic_tube() {
    let dir = tempfile::tempdir().unwrap();
    let steps = |name: &str| planned_steps(&example(name), &dir.path().join(name));
    let mesh = steps("sbend-mesh.toml");
    // The mesh's ends are sections perpendicular to the spine: compare with the tube cut so.
    let tube = planned_steps(&square_ended_sbend(dir.path()), &dir.path().join("square"));
    assert_eq!(mesh.len(), tube.len());
    for (m, t) in mesh.iter().zip(&tube) {
        assert!((m - t).abs() <= 5, "{m} vs {t} steps");
    }
    assert!(
        dir.path()
            .join("sbend-mesh.toml")
            .join("SBENDM_1.ROB")
            .exists()
    );
}

/// The geodesic of the S-bend, written to a DXF POLYLINE, planned as an imported path on the mesh
/// mandrel and on the analytic tube: the same steps as the traced path within a few.
#[test]
fn plan_takes_a_dxf_path_on_mesh_and_tube_mandrels() {
    use paths::geodesic::{Direction, PathStart};
    use sequences::dxf::{Drawing, Entity, Kind};
    let dir = tempfile::tempdir().unwrap();
    let tube = paths::Tube::new(
        paths::Spine::smoothing(
            &paths::spine::SBEND_TABLE_6_1_MM,
            paths::spine::SBEND_SMOOTHING_MM,
        )
        .unwrap(),
        28.5,
    )
    .unwrap();
    let start = PathStart {
        angle_rad: 90f64.to_radians(),
        wind_angle_rad: 45f64.to_radians(),
        direction: Direction::Down,
    };
    let path = paths::geodesic::trace(&tube, &start, 1.0).unwrap();
    let points: Vec<[f64; 3]> = path
        .samples
        .iter()
        .map(|s| {
            let p = tube.point(s.u, s.v);
            [p.x, p.y, p.z]
        })
        .collect();
    let drawing = Drawing {
        entities: vec![Entity {
            kind: Kind::Polyline,
            layer: "FIBRE".into(),
            points,
            closed: false,
            places: Vec::new(),
        }],
        units: None,
    };
    std::fs::write(dir.path().join("path.dxf"), drawing.write().unwrap()).unwrap();
    std::fs::copy(example("sbend.stl"), dir.path().join("sbend.stl")).unwrap();
    let imported = "[[path]]\nprogram = 3\ndxf = \"path.dxf\"\nlayer = \"FIBRE\"\nsegments = 50\n";
    // The traced path (program 1) ends where the drawn one does: on square ends.
    let square = std::fs::read_to_string(square_ended_sbend(dir.path())).unwrap();
    for name in ["sbend-mesh.toml", "sbend.toml"] {
        let job = match name {
            "sbend.toml" => square.clone(),
            _ => std::fs::read_to_string(example(name)).unwrap(),
        } + "\n"
            + imported;
        let job_file = dir.path().join(name);
        std::fs::write(&job_file, job).unwrap();
        let steps = planned_steps(&job_file, &dir.path().join(format!("out-{name}")));
        assert!((steps[2] - steps[0]).abs() <= 5, "{name}: {steps:?}");
    }
    // A DXF error names the file; exit 2.
    std::fs::write(
        dir.path().join("path.dxf"),
        "0\nSECTION\n2\nENTITIES\n0\nPOINT\n10\nx\n",
    )
    .unwrap();
    let r = plan(
        &dir.path().join("sbend.toml"),
        &dir.path().join("bad-out"),
        &[],
    );
    refused_naming(&r, "path.dxf:");
    assert!(!dir.path().join("bad-out").exists());
}

#[test]
fn sweep_plans_a_coverage_set_with_readable_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cover");
    let v = windcell_json(&[
        "sweep",
        example("sbend-mesh.toml").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--paths",
        "4",
        "--json",
    ]);
    assert_eq!(v["paths"].as_array().unwrap().len(), 4);
    for k in 1..=4 {
        let file = out.join(format!("SBENDM_{k}.ROB"));
        assert!(file.exists());
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&file).unwrap().permissions().mode();
            assert_ne!(mode & 0o044, 0, "readable by others: {mode:o}");
        }
    }
    let r = windcell(&[
        "sweep",
        example("sbend-mesh.toml").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--paths",
        "0",
    ]);
    assert_eq!(r.status.code(), Some(2));
}

/// Table 6.1 as a DXF spine profile plans exactly like the same knots in `spine_mm`.
#[test]
fn spine_profile_from_dxf_plans_like_spine_mm() {
    use sequences::dxf::{Drawing, Entity, Kind};
    let dir = tempfile::tempdir().unwrap();
    let drawing = Drawing {
        entities: vec![Entity {
            kind: Kind::LwPolyline,
            layer: "SPINE".into(),
            points: paths::spine::SBEND_TABLE_6_1_MM
                .iter()
                .map(|&(z, x)| [z, x, 0.0])
                .collect(),
            closed: false,
            places: Vec::new(),
        }],
        units: None,
    };
    std::fs::write(dir.path().join("spine.dxf"), drawing.write().unwrap()).unwrap();
    let text = std::fs::read_to_string(example("sbend.toml")).unwrap();
    let a = text.find("spine_mm = [").unwrap();
    let b = a + text[a..].find("]\n\n").unwrap() + 2;
    let job = format!(
        "{}spine_dxf = \"spine.dxf\"\nspine_layer = \"SPINE\"\n{}",
        &text[..a],
        &text[b..]
    );
    std::fs::write(dir.path().join("job.toml"), job).unwrap();
    let steps = |job: &Path, out: &str| planned_steps(job, &dir.path().join(out));
    assert_eq!(
        steps(&dir.path().join("job.toml"), "a"),
        steps(&example("sbend.toml"), "b")
    );
    std::fs::remove_file(dir.path().join("spine.dxf")).unwrap();
    let r = plan(&dir.path().join("job.toml"), &dir.path().join("c"), &[]);
    refused_naming(&r, "spine.dxf");
}

#[test]
fn obj_and_ascii_stl_of_the_same_mesh_trace_the_same_path() {
    let dir = tempfile::tempdir().unwrap();
    let mut outputs = Vec::new();
    for (name, extra) in [("s.obj", None), ("s.stl", Some("--ascii"))] {
        let file = dir.path().join(name);
        let job = example("sbend.toml");
        let mut args = vec![
            "triasym",
            job.to_str().unwrap(),
            "-o",
            file.to_str().unwrap(),
            "--facets",
            "32",
            "--spacing-mm",
            "10",
        ];
        args.extend(extra);
        let r = windcell(&args);
        assert!(r.status.success(), "{}", stderr(&r));
        let r = geodesic(&file, SBEND_START, "45", &[]);
        assert!(r.status.success(), "{}", stderr(&r));
        outputs.push(r.stdout);
    }
    assert_eq!(outputs[0], outputs[1]);
}

#[test]
fn the_dxf_example_plans_like_the_traced_path() {
    let dir = tempfile::tempdir().unwrap();
    let total = |name: &str| planned_steps(&example(name), &dir.path().join(name))[0];
    assert!((total("sbend-dxf.toml") - total("sbend.toml")).abs() <= 2);
}
