//! A coverage set (`windcell sweep`): a job's first traced path repeated around the mandrel, at
//! start angles `360°/N` apart, programs 1…N. The expansion is one function so that `windcell run
//! --job` recognises a sweep's files as the plan of the job they came from.

use std::num::NonZeroU8;
use std::path::Path;

use sequences::Job;
use toml::Spanned;

use crate::Error;

/// `job` (read from `file`) with its paths replaced by `paths` copies of its first traced path (no `dxf`), the
/// k-th (from 0) starting `360° · k / paths` after the pattern's start angle. Each copy keeps
/// the pattern's spans, so an error in a copy points at the pattern's line.
pub fn expand(job: &Job, file: &Path, paths: NonZeroU8) -> Result<Job, Error> {
    let paths = paths.get();
    let Some(pattern) = job.paths.iter().find(|p| p.dxf.is_none()).cloned() else {
        return Err(Error::NoSweepPattern {
            job: file.to_path_buf(),
        });
    };
    let start = pattern
        .start_angle_deg
        .as_ref()
        .map_or(0.0, |s| *s.get_ref());
    let span = pattern
        .start_angle_deg
        .as_ref()
        .map_or(pattern.program.span(), |s| s.span());
    let mut swept = job.clone();
    swept.paths = (0..paths)
        .map(|k| {
            let mut p = pattern.clone();
            p.program = Spanned::new(pattern.program.span(), k + 1);
            p.start_angle_deg = Some(Spanned::new(
                span.clone(),
                start + 360.0 * f64::from(k) / f64::from(paths),
            ));
            p
        })
        .collect();
    Ok(swept)
}
