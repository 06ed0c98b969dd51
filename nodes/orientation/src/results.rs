//! The orientation's result files: `poses.csv`, `checkpoints.csv`, the COLMAP text model `colmap/` and, when the
//! camera was self-calibrated, `camera_calibrated.toml` with the interior's precision.
use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result};
use lineflow_formats::project::write_camera;
use lineflow_formats::{write_checkpoints, write_poses, CheckRow, PoseRow};

use crate::calibration_report::{interior_header, CALIBRATED_CAMERA};
use crate::stage::pose_elements;
use crate::Block;

/// Writes `poses.csv` and the COLMAP text model into `dir` and, when the block is in the control frame,
/// `checkpoints.csv`; says in the log what could not be written and why.
///
/// # Errors
/// A file that cannot be written.
pub fn write_results(dir: &Path, block: &Block, names: &BTreeMap<u64, String>) -> Result<()> {
    let rows: Vec<PoseRow> = pose_elements(block)
        .iter()
        .map(|p| PoseRow {
            image: names.get(&p.frame).cloned().unwrap_or_else(|| format!("frame_{:05}", p.frame)),
            pose: p.exterior(),
            sigma_center_m: p.sigma_center_m[0].is_finite().then_some(p.sigma_center_m),
            sigma_angles_deg: p.sigma_angles_rad[0].is_finite().then(|| p.sigma_angles_rad.map(f64::to_degrees)),
        })
        .collect();
    let path = dir.join("poses.csv");
    write_poses(&path, &rows).with_context(|| format!("writing {}", path.display()))?;
    if let Some(interior) = block.report.interior.as_ref().filter(|_| block.finished) {
        let path = dir.join(CALIBRATED_CAMERA);
        write_camera(&path, &interior.camera, &interior_header(interior)).with_context(|| format!("writing {}", path.display()))?;
        tracing::info!("self-calibrated camera in {}", path.display());
    }
    if !block.poses.is_empty() {
        let colmap_dir = dir.join("colmap");
        let name = |f: u64| names.get(&f).cloned().unwrap_or_else(|| format!("frame_{f:05}"));
        let worst = crate::colmap::write_text_model(&colmap_dir, block.camera(), &block.poses, &name, &block.points())
            .with_context(|| format!("writing the COLMAP model into {}", colmap_dir.display()))?;
        tracing::info!(
            "COLMAP text model in {} (distortion fitted within {worst:.3} px)",
            colmap_dir.display()
        );
    }
    if block.poses.is_empty() {
        tracing::warn!("no frame could be oriented (too few verified tie points): poses.csv has no rows");
        return Ok(());
    }
    if !block.georeferenced {
        tracing::warn!(
            "fewer than three control points were intersected: poses.csv is in the arbitrary frame of the first pair, \
             and no checkpoints.csv is written"
        );
        return Ok(());
    }
    let checks: Vec<CheckRow> = block
        .check_points()
        .into_iter()
        .map(|(id, d)| CheckRow { id, delta_m: d.into() })
        .collect();
    let path = dir.join("checkpoints.csv");
    write_checkpoints(&path, &checks).with_context(|| format!("writing {}", path.display()))?;
    let n = checks.len().max(1) as f64;
    let rmse: Vec<f64> = (0..3)
        .map(|k| (checks.iter().map(|c| c.delta_m[k].powi(2)).sum::<f64>() / n).sqrt() * 1e3)
        .collect();
    tracing::info!(
        "{} check points, RMSE X {:.1} Y {:.1} Z {:.1} mm",
        checks.len(),
        rmse[0],
        rmse[1],
        rmse[2]
    );
    // A block that converged to a wrong solution still reports σ0 near 1 (its own tie points agree); the check
    // points do not. Seen on a held-out building: check points 3 to 11 m off at a GSD of 23 mm, the run "ok".
    let rmse_3d_m = rmse.iter().map(|r| r * r).sum::<f64>().sqrt() * 1e-3;
    if let Some(alarm) = block.check_point_gsd_m().and_then(|gsd| check_point_alarm(rmse_3d_m, gsd)) {
        tracing::warn!("{alarm}");
    }
    Ok(())
}

/// The warning a failed orientation gets: check points `rmse_3d_m` (3-D RMS) off at a check-point GSD of `gsd_m`,
/// when that exceeds [`CHECK_POINT_ALARM_GSD`].
fn check_point_alarm(rmse_3d_m: f64, gsd_m: f64) -> Option<String> {
    (gsd_m > 0.0 && rmse_3d_m > CHECK_POINT_ALARM_GSD * gsd_m).then(|| {
        format!(
            "the check points lie {:.3} m (RMS) off, {:.0} GSD: the orientation failed (a wrong solution of the block or a control point measured on the wrong target); poses, 3-D lines and model are not to be trusted",
            rmse_3d_m,
            rmse_3d_m / gsd_m
        )
    })
}

/// Check points farther off than this many GSD (3-D RMSE) mean a failed orientation; a sound block puts them within
/// one or two.
const CHECK_POINT_ALARM_GSD: f64 = 20.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_points_far_off_say_the_orientation_failed_and_sound_ones_say_nothing() {
        // The held-out building whose block converged wrongly: 12 m off at a GSD of 23 mm.
        let alarm = check_point_alarm(12.2, 0.023).expect("a failed orientation is named");
        assert!(
            alarm.contains("12.200 m") && alarm.contains("530 GSD") && alarm.contains("orientation failed"),
            "{alarm}"
        );
        // A sound block (one or two GSD), the limit itself, and a block without a GSD (no check point seen).
        assert_eq!(check_point_alarm(0.046, 0.023), None);
        assert_eq!(check_point_alarm(20.0 * 0.023, 0.023), None);
        assert!(check_point_alarm(20.1 * 0.023, 0.023).is_some());
        assert_eq!(check_point_alarm(5.0, 0.0), None);
    }
}
