//! DXF files on disk: a path exported as POINTs (seed 001 §5.5, Fig 5.8) and a spine profile as
//! an LWPOLYLINE, written, loaded back and read; errors name the file.

use sequences::Error;
use sequences::dxf::{Drawing, Entity, Kind};

#[test]
fn path_and_profile_files_load_from_disk() {
    let dir = tempfile::tempdir().unwrap();
    let path_points: Vec<[f64; 3]> = (0..12)
        .map(|i| {
            let a = i as f64 * 0.3;
            [28.5 * a.cos(), 28.5 * a.sin(), 10.0 * i as f64]
        })
        .collect();
    let drawing = Drawing {
        entities: path_points
            .iter()
            .map(|&p| Entity {
                kind: Kind::Point,
                layer: "PATH".into(),
                points: vec![p],
                closed: false,
                places: Vec::new(),
            })
            .chain(std::iter::once(Entity {
                kind: Kind::LwPolyline,
                layer: "SPINE".into(),
                points: vec![[0.0, 0.0, 0.0], [10.0, 0.4, 0.0], [20.0, 1.6, 0.0]],
                closed: false,
                places: Vec::new(),
            }))
            .collect(),
        units: None,
    };
    let file = dir.path().join("SBEND.DXF");
    // AutoCAD writes CRLF; the reader takes either.
    std::fs::write(&file, drawing.write().unwrap().replace('\n', "\r\n")).unwrap();
    let loaded = Drawing::load(&file).unwrap();
    assert_eq!(loaded, drawing);
    assert_eq!(loaded.path(Some("PATH")).unwrap(), path_points);
    assert_eq!(
        loaded.profile(Some("SPINE")).unwrap(),
        vec![(0.0, 0.0), (10.0, 0.4), (20.0, 1.6)]
    );
}

#[test]
fn errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("CUT.DXF");
    std::fs::write(
        &file,
        "  0\r\nSECTION\r\n  2\r\nENTITIES\r\n  0\r\nPOINT\r\n 10\r\n",
    )
    .unwrap();
    let e = Drawing::load(&file).unwrap_err();
    let text = e.to_string();
    assert!(
        text.starts_with(&format!("{}:8:1:", file.display())),
        "{text}"
    );
    assert!(text.contains("truncated"), "{text}");
    assert!(matches!(
        Drawing::load(&dir.path().join("none.dxf")),
        Err(Error::Io { .. })
    ));
    // A drawing with no path is a content error naming the file.
    let empty = dir.path().join("EMPTY.DXF");
    std::fs::write(&empty, Drawing::default().write().unwrap()).unwrap();
    let e = Drawing::load(&empty)
        .unwrap()
        .path(None)
        .map_err(|e| e.in_file(&empty))
        .unwrap_err();
    assert!(
        e.to_string().starts_with(&format!("{}: ", empty.display())),
        "{e}"
    );
}
