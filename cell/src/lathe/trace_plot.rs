//! SVG plots of a lathe run's trace (`windcell lathe run --plot`): the X axis's desired and actual
//! positions against time, and its following error, drawn with `plotters`' SVG backend (no system
//! fonts: the backend writes text elements and sizes them by estimate).

use std::path::Path;

use plotters::prelude::*;

use crate::Error;
use crate::lathe::TraceRow;

/// Writes `rows` as a two-panel SVG (X desired and actual, X following error) titled `title`.
pub fn write_svg(path: &Path, rows: &[TraceRow], title: &str) -> Result<(), Error> {
    let fail = |e: String| Error::Output {
        path: path.to_path_buf(),
        source: std::io::Error::other(e),
    };
    if rows.len() < 2 {
        return Err(fail(
            "nothing to plot: the trace has fewer than two rows".into(),
        ));
    }
    let t_end = rows[rows.len() - 1].time_s;
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut err_max = 0.0f64;
    for r in rows {
        lo = lo.min(r.desired[1]).min(r.actual[1]);
        hi = hi.max(r.desired[1]).max(r.actual[1]);
        err_max = err_max.max((r.desired[1] - r.actual[1]).abs());
    }
    let err_max = err_max.max(0.5) * 1.1;
    let margin = (hi - lo).max(1.0) * 0.05;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 600)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(e.to_string()))?;
        let (top, bottom) = root.split_vertically(360);
        let mut chart = ChartBuilder::on(&top)
            .caption(title, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..t_end, (lo - margin)..(hi + margin))
            .map_err(|e| fail(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("time, s")
            .y_desc("X, mm")
            .draw()
            .map_err(|e| fail(e.to_string()))?;
        chart
            .draw_series(LineSeries::new(
                rows.iter().map(|r| (r.time_s, r.desired[1])),
                &BLUE,
            ))
            .map_err(|e| fail(e.to_string()))?
            .label("desired")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
        chart
            .draw_series(LineSeries::new(
                rows.iter().map(|r| (r.time_s, r.actual[1])),
                &RED,
            ))
            .map_err(|e| fail(e.to_string()))?
            .label("actual")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
        chart
            .configure_series_labels()
            .background_style(WHITE)
            .border_style(BLACK)
            .draw()
            .map_err(|e| fail(e.to_string()))?;
        let mut err = ChartBuilder::on(&bottom)
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..t_end, -err_max..err_max)
            .map_err(|e| fail(e.to_string()))?;
        err.configure_mesh()
            .x_desc("time, s")
            .y_desc("X following error, mm")
            .draw()
            .map_err(|e| fail(e.to_string()))?;
        for band in [-0.5, 0.5] {
            err.draw_series(LineSeries::new(
                [(0.0, band), (t_end, band)],
                &BLACK.mix(0.4),
            ))
            .map_err(|e| fail(e.to_string()))?;
        }
        err.draw_series(LineSeries::new(
            rows.iter().map(|r| (r.time_s, r.desired[1] - r.actual[1])),
            &RED,
        ))
        .map_err(|e| fail(e.to_string()))?;
        root.present().map_err(|e| fail(e.to_string()))?;
    }
    std::fs::write(path, svg).map_err(|source| Error::Output {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_an_svg_with_both_panels() {
        let rows: Vec<TraceRow> = (0..100)
            .map(|k| TraceRow {
                interrupt: k,
                time_s: k as f64 / 200.0,
                desired: [0.0, k as f64, 0.0],
                actual: [0.0, k as f64 - 0.3, 0.0],
            })
            .collect();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.svg");
        write_svg(&path, &rows, "test").unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("<svg"));
        assert!(text.contains("desired") && text.contains("following error"));
        assert!(write_svg(&path, &rows[..1], "x").is_err());
    }
}
