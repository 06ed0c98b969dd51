//! Orientation: camera centre and rotation errors against the true poses, check-point RMSE per axis.
use crate::Truth;
use lineflow_formats::{CheckRow, PoseRow};

/// Errors of one image.
pub struct ImageError {
    pub image: String,
    /// Estimated minus true centre, metres.
    pub center_m: [f64; 3],
    /// Angle of the rotation between estimated and true attitude, degrees.
    pub rotation_deg: f64,
}

pub struct OrientationReport {
    pub images: Vec<ImageError>,
    /// Images in the ground truth without an estimate.
    pub missing: Vec<String>,
    pub rms_center_m: f64,
    pub max_center_m: f64,
    pub rms_rotation_deg: f64,
    pub max_rotation_deg: f64,
    /// RMSE of the check points per axis, metres, and their number.
    pub checkpoints: Option<([f64; 3], usize)>,
}

pub fn evaluate(truth: &Truth, poses: &[PoseRow], checks: Option<&[CheckRow]>) -> OrientationReport {
    let mut images = Vec::new();
    let mut missing = Vec::new();
    for gt in &truth.poses {
        let Some(est) = poses.iter().find(|p| p.image == gt.image) else {
            missing.push(gt.image.clone());
            continue;
        };
        let d = est.pose.center - gt.pose.center;
        let r = est.pose.rotation * gt.pose.rotation.transpose();
        let cos = ((r.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
        images.push(ImageError {
            image: gt.image.clone(),
            center_m: [d.x, d.y, d.z],
            rotation_deg: cos.acos().to_degrees(),
        });
    }
    let rms = |v: &mut dyn Iterator<Item = f64>| {
        let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
        if n == 0 {
            f64::NAN
        } else {
            (s / n as f64).sqrt()
        }
    };
    let norm = |c: &[f64; 3]| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
    let checkpoints = checks.filter(|c| !c.is_empty()).map(|c| {
        let axis = |k: usize| rms(&mut c.iter().map(|r| r.delta_m[k]));
        ([axis(0), axis(1), axis(2)], c.len())
    });
    OrientationReport {
        rms_center_m: rms(&mut images.iter().map(|e| norm(&e.center_m))),
        max_center_m: images.iter().map(|e| norm(&e.center_m)).fold(f64::NAN, f64::max),
        rms_rotation_deg: rms(&mut images.iter().map(|e| e.rotation_deg)),
        max_rotation_deg: images.iter().map(|e| e.rotation_deg).fold(f64::NAN, f64::max),
        images,
        missing,
        checkpoints,
    }
}
