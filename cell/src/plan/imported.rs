//! Fibre paths imported from DXF drawings (seed 001 §5.5: the segment end points "were stored in
//! a .DXF file format"), checked before anything is planned:
//!
//! - the drawing's units come from `$INSUNITS` (absent: millimetres; see `docs/file-formats.md`);
//! - the path's length is held to [`paths::limits::MAX_PATH_LENGTH_MM`] (100 m) before anything
//!   is sampled: a longer path is refused at the coordinate that makes it so;
//! - every point's distance to the mandrel surface is measured, and a point farther than the
//!   job's `surface_tolerance_mm` (default 0.5 mm) refuses the plan at the point's place in the
//!   drawing. A drawing in metres without `$INSUNITS`, or a path shifted off the mandrel, stops
//!   here.

use std::path::{Path, PathBuf};

use nalgebra::Point3;
use paths::limits::MAX_PATH_LENGTH_MM;
use sequences::dxf::{Drawing, Place};

use crate::Error;

/// A path read from a DXF drawing, in millimetres, with where each point was read.
#[derive(Debug, Clone)]
pub struct ImportedPath {
    /// The drawing.
    pub file: PathBuf,
    /// What the drawing's units are, in words (`millimetres (no $INSUNITS)`).
    pub units: String,
    /// The path's points, mandrel frame, mm.
    pub points: Vec<Point3<f64>>,
    /// Where each point's x, y and z values stand in the drawing.
    pub places: Vec<[Place; 3]>,
}

impl ImportedPath {
    /// The path on `layer` (any layer for `None`) of `drawing`, read from `file`.
    pub fn new(file: &Path, drawing: &Drawing, layer: Option<&str>) -> Result<Self, Error> {
        let points = drawing
            .path_points(layer)
            .map_err(|e| Error::File(e.in_file(file)))?;
        let units = match drawing.units {
            Some(u) => format!("{} ($INSUNITS)", u.name()),
            None => "millimetres (no $INSUNITS)".to_string(),
        };
        // A parsed drawing places every coordinate; line 1 stands in for none.
        let first = Place { line: 1, column: 1 };
        Ok(ImportedPath {
            file: file.to_path_buf(),
            units,
            places: points
                .iter()
                .map(|p| p.places.unwrap_or([first; 3]))
                .collect(),
            points: points.iter().map(|p| Point3::from(p.mm)).collect(),
        })
    }

    /// Refuses a path longer than [`MAX_PATH_LENGTH_MM`] at the first point from which it is
    /// (its coordinate farthest from the previous point's), before anything is sampled.
    pub fn check_length(&self) -> Result<(), Error> {
        let limit_mm = MAX_PATH_LENGTH_MM;
        let mut length_mm = 0.0;
        for (k, w) in self.points.windows(2).enumerate() {
            length_mm += (w[1] - w[0]).norm();
            // An infinite or NaN length (finite coordinates can still overflow) is refused too.
            if length_mm.is_nan() || length_mm > limit_mm {
                let jump = w[1] - w[0];
                let axis = (0..3)
                    .max_by(|&a, &b| jump[a].abs().total_cmp(&jump[b].abs()))
                    .unwrap_or(0);
                // The point of the two that stands out: the one farther from the origin.
                let index = if w[1].coords.norm() >= w[0].coords.norm() {
                    k + 1
                } else {
                    k
                };
                let place = self.places[index][axis];
                return Err(Error::PathTooLong {
                    file: self.file.clone(),
                    line: place.line,
                    column: place.column,
                    point: index + 1,
                    value_mm: self.points[index][axis],
                    limit_mm,
                });
            }
        }
        Ok(())
    }

    /// Each point's signed distance to the mandrel surface (`distance`, mm, negative inside);
    /// refuses the first point farther than `tolerance_mm`, at its place in the drawing.
    pub fn surface_distances(
        &self,
        distance: impl Fn(&Point3<f64>) -> f64,
        tolerance_mm: f64,
    ) -> Result<Vec<f64>, Error> {
        let distances: Vec<f64> = self.points.iter().map(distance).collect();
        if let Some(index) = distances
            .iter()
            .position(|d| d.is_nan() || d.abs() > tolerance_mm)
        {
            let place = self.places[index][0];
            return Err(Error::OffSurface {
                file: self.file.clone(),
                line: place.line,
                column: place.column,
                point: index + 1,
                distance_mm: distances[index],
                worst_mm: distances.iter().fold(0.0f64, |w, d| w.max(d.abs())),
                tolerance_mm,
                units: self.units.clone(),
            });
        }
        Ok(distances)
    }
}
