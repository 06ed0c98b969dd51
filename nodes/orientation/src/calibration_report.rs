//! What a self-calibrating adjustment tells the user: the adjusted parameters with their σ and correlations, as
//! the header of `camera_calibrated.toml` and as log lines, and a warning where the block cannot tell the principal
//! distance from the distance to the object.
use lineflow_photogrammetry::{Interior, InteriorReport};

/// The self-calibrated camera's file in the run's output folder.
pub const CALIBRATED_CAMERA: &str = "camera_calibrated.toml";

/// Comment lines for the self-calibrated camera's file: each estimated parameter with its σ, and the strongest
/// correlations.
pub fn interior_header(r: &InteriorReport) -> String {
    let mut out = String::from("# Self-calibrated by lineflow's bundle adjustment (value, sigma):\n");
    for &p in &r.free {
        out += &format!(
            "#   {:<2} = {:.6e} ± {:.1e} {}\n",
            p.name(),
            p.value(&r.camera),
            r.sigmas[p.index()],
            p.unit()
        );
    }
    if let Some((a, b, rho)) = r.strongest_correlation() {
        out += &format!("#   strongest correlation: {} / {} {:+.2}\n", a.name(), b.name(), rho);
    }
    if r.focal_exterior_correlation.is_finite() {
        out += &format!(
            "#   principal distance against the camera positions: {:+.2}\n",
            r.focal_exterior_correlation
        );
    }
    out
}

/// A warning when the block cannot tell the principal distance from the distance to the object: a flat façade
/// photographed from one strip, square on.
pub fn weak_calibration(r: &InteriorReport) -> Option<String> {
    let f = Interior::Focal.index();
    let relative = r.sigmas[f] / r.camera.focal_mm;
    (r.focal_exterior_correlation.abs() > WEAK_CORRELATION || relative > WEAK_FOCAL_SIGMA).then(|| {
        format!(
            "self-calibration is weak: the principal distance is {:.3} ± {:.3} mm and correlates {:+.2} with the \
             camera positions (a flat façade from one strip, square on, cannot separate them); add control points, \
             a second strip at another height or oblique photos, or give the principal distance in camera.toml",
            r.camera.focal_mm, r.sigmas[f], r.focal_exterior_correlation
        )
    })
}

/// Correlation of the principal distance with a camera position beyond which self-calibration is called weak.
const WEAK_CORRELATION: f64 = 0.95;
/// Relative standard deviation of the principal distance beyond which self-calibration is called weak.
const WEAK_FOCAL_SIGMA: f64 = 0.005;
