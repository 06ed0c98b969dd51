//! `lineflow process` on a folder whose camera is nominal (written from a photo's EXIF): the self-calibration pass
//! that replaces it with the camera the bundle adjustment estimates.
use std::path::Path;
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use lineflow_runtime::launch::{self, Resolver};
use lineflow_runtime::run::{launch_dir, run_graph, Verbosity};

/// Whether `camera_toml` holds a nominal camera (written from EXIF, never calibrated).
pub fn is_nominal(camera_toml: &Path) -> bool {
    std::fs::read_to_string(camera_toml).is_ok_and(|t| t.starts_with(crate::NOMINAL_CAMERA_HEADER))
}

/// The first pass over a folder with a nominal camera: `launch/calibrate.toml` estimates the interior orientation
/// in the bundle adjustment (the parameters it names, or `orientation.self_calibrate` as set), and the result
/// replaces the folder's `camera.toml` (the nominal one stays beside it as `camera_nominal.toml`), so the main
/// graph and every later run use it. `orientation.self_calibrate=[]` keeps the nominal camera.
///
/// # Errors
/// The graph cannot be loaded or run, or orients too few images to calibrate, or a file cannot be written.
pub fn self_calibrate(folder: &Path, out: &Path, set: &[String], verbosity: Verbosity) -> Result<Option<std::path::PathBuf>> {
    let out = out.join("calibration");
    let set = settings_of(set, &["capture.", "orientation.", "features.", "matcher."]);
    if set.iter().any(|s| s.replace(' ', "") == "orientation.self_calibrate=[]") {
        eprintln!("warning: the camera is nominal and orientation.self_calibrate = []: it is used as it is");
        return Ok(None);
    }
    eprintln!(
        "self-calibration: the camera is nominal; estimating its interior orientation first ({})",
        launch_dir().join("calibrate.toml").display()
    );
    let status = run_orientation_pass(&set, &out, verbosity)?;
    let calibrated = out.join("camera_calibrated.toml");
    if status != ExitCode::SUCCESS || !calibrated.is_file() {
        bail!(
            "self-calibration failed (logs in {}): too few images could be oriented with the nominal camera; \
             calibrate the camera (`lineflow camera import`) and run again",
            out.join("logs").display()
        );
    }
    let camera_toml = folder.join("camera.toml");
    let nominal = folder.join("camera_nominal.toml");
    std::fs::copy(&camera_toml, &nominal).with_context(|| format!("keeping the nominal camera as {}", nominal.display()))?;
    let text = std::fs::read_to_string(&calibrated).with_context(|| format!("{}", calibrated.display()))?;
    let header = format!(
        "# Self-calibrated by `lineflow process` ({}); the nominal camera it started from is {}. Delete this file and\n\
         # rename that one back to calibrate again.\n",
        out.display(),
        nominal.display()
    );
    std::fs::write(&camera_toml, header + &text).with_context(|| format!("writing {}", camera_toml.display()))?;
    eprintln!("self-calibration: {} now holds the adjusted camera", camera_toml.display());
    Ok(Some(out.join("poses.csv")))
}

/// The `--set` values among `set` that name one of the `stages` (`"capture."`, ...): those of the orientation
/// graph's stages.
pub(crate) fn settings_of(set: &[String], stages: &[&str]) -> Vec<String> {
    set.iter().filter(|s| stages.iter().any(|p| s.starts_with(p))).cloned().collect()
}

/// `launch/calibrate.toml` (the graph that stops at the orientation) run into `out` with `set`.
pub(crate) fn run_orientation_pass(set: &[String], out: &Path, verbosity: Verbosity) -> Result<ExitCode> {
    let g = launch::load(&launch_dir().join("calibrate.toml"), set, &Resolver::beside_current_exe())?;
    run_graph(&g, out, None, verbosity)
}
