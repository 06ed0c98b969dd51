//! Bare photos: the passes `lineflow process` runs over a project folder before its main graph, so that photos
//! with no camera file (a nominal camera from EXIF) and surveyed points with no observations still run.
use std::path::Path;

use anyhow::{Context, Result};
use lineflow_runtime::run::Verbosity;

use crate::{calibrate, targets};

/// Self-calibrates a nominal camera ([`calibrate::self_calibrate`]) and, where the folder has surveyed points and
/// no observations, finds them in the images ([`targets::observe`]). The first self-calibration has no control
/// points, and its camera fits the block only up to what a free network fixes (on a synthetic façade the check
/// points then lie 16 mm off in depth against 1.6 mm with the true camera); with the targets' observations it runs
/// again from the nominal camera, the control points in the adjustment.
///
/// # Errors
/// A pass fails, the targets cannot be named, or the nominal camera cannot be put back for the second pass.
pub fn prepare(folder: &Path, out: &Path, set: &[String], verbosity: Verbosity) -> Result<()> {
    let camera = folder.join("camera.toml");
    let calibration = if calibrate::is_nominal(&camera) {
        calibrate::self_calibrate(folder, out, set, verbosity)?
    } else {
        None
    };
    if targets::wanted(folder) {
        let calibrated = calibration.is_some();
        targets::observe(folder, out, calibration, set, verbosity)?;
        if calibrated {
            eprintln!("self-calibration: again, with the control points the targets gave");
            let nominal = folder.join("camera_nominal.toml");
            std::fs::copy(&nominal, &camera).with_context(|| format!("putting {} back", nominal.display()))?;
            calibrate::self_calibrate(folder, out, set, verbosity)?;
        }
    }
    Ok(())
}
