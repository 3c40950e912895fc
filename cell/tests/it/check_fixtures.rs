//! The seeded collision and snag fixtures of `examples/`: each states in a comment line
//! `# expect: path N segment M` what the check must report first (worked out without the check,
//! as its comment says), and `windcell check` names exactly that with exit code 3. Every other
//! robot-cell example checks clear. The snag fixture's mesh is generated here, from its documented
//! profile, and must equal the shipped file byte for byte (`WINDCELL_WRITE_FIXTURES=1 cargo test
//! -p cell --test check_fixtures` rewrites it).

use crate::common;

use common::{example, windcell};
use paths::mesh::{stl, triasym};

/// The seeded fixtures.
const FIXTURES: [&str; 3] = ["sbend-too-close.toml", "snag.toml", "arm-hits-frame.toml"];

/// `(path, segment)` of the `# expect: path N segment M` line of a fixture.
fn expected(text: &str) -> (usize, usize) {
    let line = text
        .lines()
        .find_map(|l| l.strip_prefix("# expect: "))
        .expect("an `# expect:` line");
    let words: Vec<&str> = line.split_whitespace().collect();
    assert_eq!(
        (words.len(), words[0], words[2]),
        (4, "path", "segment"),
        "{line}"
    );
    (words[1].parse().unwrap(), words[3].parse().unwrap())
}

#[test]
fn each_fixture_reports_its_expected_first_finding() {
    for name in FIXTURES {
        let file = example(name);
        let text = std::fs::read_to_string(&file).unwrap();
        let (path, segment) = expected(&text);
        // The plan accepts the job (its eye points are outside the mandrel).
        let dir = tempfile::tempdir().unwrap();
        let plan = windcell(&[
            "plan",
            file.to_str().unwrap(),
            "-o",
            dir.path().to_str().unwrap(),
        ]);
        assert_eq!(
            plan.status.code(),
            Some(0),
            "{name}: {}",
            String::from_utf8_lossy(&plan.stderr)
        );
        let out = windcell(&["check", file.to_str().unwrap(), "--json"]);
        assert_eq!(out.status.code(), Some(3), "{name}");
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let first = &v["findings"][0];
        assert_eq!(
            (first["path"].as_u64(), first["segment"].as_u64()),
            (Some(path as u64), Some(segment as u64)),
            "{name}: {first}"
        );
        let part = first["part"].as_str().unwrap();
        let wanted = match name {
            "sbend-too-close.toml" => "eye mechanism",
            "snag.toml" => "free fibre",
            _ => "forearm",
        };
        assert_eq!(part, wanted, "{name}: {first}");
    }
}

#[test]
fn every_other_robot_cell_example_checks_clear() {
    let mut checked = 0;
    for entry in std::fs::read_dir(example("")).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_str().unwrap().to_string();
        if path.extension().is_none_or(|e| e != "toml") || FIXTURES.contains(&name.as_str()) {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        // Cell files and the analytic-vessel job are not robot-cell jobs with paths.
        if !text.contains("[[path]]") {
            continue;
        }
        let out = windcell(&["check", path.to_str().unwrap()]);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{name}: {stdout}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(stdout.starts_with("check: clear"), "{name}: {stdout}");
        checked += 1;
    }
    // The seven analytic examples, the DXF path and the mesh mandrel.
    assert!(checked >= 9, "{checked} examples checked");
}

/// The snag fixture's mandrel: a cylinder of radius 28.5 mm and 200 mm long with a smooth ring
/// (a ridge) 5 mm high between 120 and 140 mm, `R(z) = 28.5 + 5 sin²(π (z − 120) / 20)`; 64
/// facets around, sections every 4 mm and every 1 mm over the ridge, closed by flat caps.
fn snag_mesh() -> Vec<u8> {
    let mut profile: Vec<(f64, f64)> = Vec::new();
    let mut z = 0.0;
    while z <= 200.0 {
        let r = if (120.0..=140.0).contains(&z) {
            28.5 + 5.0 * (std::f64::consts::PI * (z - 120.0) / 20.0).sin().powi(2)
        } else {
            28.5
        };
        profile.push((z, r));
        z += if (116.0..140.0).contains(&z) {
            1.0
        } else {
            4.0
        };
    }
    let mesh = triasym::revolution(&profile, 64, true).unwrap();
    stl::write_binary(&mesh, "windcell snag fixture: cylinder with a ridge")
}

#[test]
fn the_snag_mesh_is_the_documented_ridge() {
    let bytes = snag_mesh();
    let file = example("snag.stl");
    if std::env::var_os("WINDCELL_WRITE_FIXTURES").is_some() {
        std::fs::write(&file, &bytes).unwrap();
    }
    let shipped = std::fs::read(&file).unwrap();
    assert!(
        shipped == bytes,
        "examples/snag.stl differs from its profile"
    );
}
