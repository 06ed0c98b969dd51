//! The oriented block as a COLMAP text model (`cameras.txt`, `images.txt`, `points3D.txt`), for other tools
//! (COLMAP, OpenMVS, Nerfstudio, …) to start from lineflow's orientation.
//!
//! COLMAP's camera looks along +z with y down and pixel centres at +0.5; ours looks along −z with y up and pixel
//! centres at integers (`conventions.md`), so the rotation is `diag(1, −1, −1) · M` and pixels shift by half a
//! pixel. COLMAP's distortion maps ideal to measured coordinates while ours corrects measured ones, so the
//! `FULL_OPENCV` coefficients are fitted to our model over the image by least squares; the fit's worst error is
//! returned so that the caller can report it.
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use lineflow_photogrammetry::{opencv_from_camera, Camera, Mat3, Pose, Vec3};
use nalgebra::UnitQuaternion;

/// One intersected tie point: its object coordinates and its (frame, measured pixel) observations.
pub type TrackPoint = (Vec3, Vec<(u64, [f64; 2])>);

/// COLMAP's camera frame from ours.
fn flip() -> Mat3 {
    Mat3::from_diagonal(&Vec3::new(1.0, -1.0, -1.0))
}

/// `FULL_OPENCV` parameters `fx fy cx cy k1 k2 p1 p2 k3 k4 k5 k6` fitted to `camera`
/// ([`lineflow_photogrammetry::opencv_from_camera`]), and the fit's largest error in pixels over a grid covering the
/// image.
pub fn opencv_parameters(camera: &Camera) -> ([f64; 12], f64) {
    let Some((l, fit)) = opencv_from_camera(camera) else {
        // No fit (a degenerate camera): the pinhole, its error unknown.
        let fpx = camera.focal_mm / camera.pixel_size_mm;
        let c = camera.photo_to_pixel(camera.principal_point_mm);
        return ([fpx, fpx, c[0] + 0.5, c[1] + 0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], f64::NAN);
    };
    (lineflow_formats::colmap::full_opencv_params(&l), fit.max_px)
}

/// Writes `cameras.txt`, `images.txt` and `points3D.txt` into `dir` (created); returns the distortion fit's
/// largest error in pixels.
pub fn write_text_model(
    dir: &Path,
    camera: &Camera,
    poses: &BTreeMap<u64, Pose>,
    names: &dyn Fn(u64) -> String,
    points: &[TrackPoint],
) -> std::io::Result<f64> {
    std::fs::create_dir_all(dir)?;
    let (params, worst) = opencv_parameters(camera);
    let mut cameras = String::from("# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n");
    let _ = write!(cameras, "1 FULL_OPENCV {} {}", camera.width, camera.height);
    for p in params {
        let _ = write!(cameras, " {p:.12e}");
    }
    cameras.push('\n');
    std::fs::write(dir.join("cameras.txt"), cameras)?;

    // Per image, its 2-D points in order: (x, y, point id).
    let mut per_image: BTreeMap<u64, Vec<(f64, f64, usize)>> = poses.keys().map(|&f| (f, Vec::new())).collect();
    let mut lines3d = String::from(
        "# 3D point list with one line of data per point:\n#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n",
    );
    for (id, (xyz, obs)) in points.iter().enumerate() {
        let mut track = String::new();
        let mut error = 0.0;
        let mut n = 0.0;
        for &(frame, px) in obs {
            let (Some(list), Some(pose)) = (per_image.get_mut(&frame), poses.get(&frame)) else {
                continue;
            };
            let _ = write!(track, " {} {}", frame + 1, list.len());
            list.push((px[0] + 0.5, px[1] + 0.5, id + 1));
            if let Some(p) = pose.project(camera, xyz) {
                error += (p[0] - px[0]).hypot(p[1] - px[1]);
                n += 1.0;
            }
        }
        let _ = writeln!(
            lines3d,
            "{} {:.6} {:.6} {:.6} 128 128 128 {:.4}{track}",
            id + 1,
            xyz.x,
            xyz.y,
            xyz.z,
            if n > 0.0 { error / n } else { 0.0 }
        );
    }
    let mut images = String::from(
        "# Image list with two lines of data per image:\n#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n#   POINTS2D[] as (X, Y, POINT3D_ID)\n",
    );
    for (&frame, pose) in poses {
        let r = flip() * pose.rotation;
        let q = UnitQuaternion::from_matrix(&r);
        let t = -(r * pose.center);
        let _ = writeln!(
            images,
            "{} {:.12} {:.12} {:.12} {:.12} {:.9} {:.9} {:.9} 1 {}",
            frame + 1,
            q.w,
            q.i,
            q.j,
            q.k,
            t.x,
            t.y,
            t.z,
            names(frame)
        );
        let pts: Vec<String> = per_image[&frame].iter().map(|(x, y, id)| format!("{x:.3} {y:.3} {id}")).collect();
        images.push_str(&pts.join(" "));
        images.push('\n');
    }
    std::fs::write(dir.join("images.txt"), images)?;
    std::fs::write(dir.join("points3D.txt"), lines3d)?;
    Ok(worst)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_opencv_fit_reproduces_a_distorted_camera_within_two_tenths_of_a_pixel() {
        let camera = Camera {
            width: 4288,
            height: 2848,
            pixel_size_mm: 0.0055,
            focal_mm: 24.0,
            principal_point_mm: [0.05, -0.03],
            radial: [-2.0e-4, 3.0e-7, 0.0],
            decentering: [1.0e-5, -2.0e-5],
        };
        let (p, worst) = opencv_parameters(&camera);
        // The two models are inverse forms of each other; over a strongly distorted 12 MP frame they agree to 0.09 px.
        assert!(worst < 0.2, "fit error {worst} px");
        assert!((p[0] - 24.0 / 0.0055).abs() < 1e-9 && p[4] != 0.0);
    }

    #[test]
    fn a_projected_point_lands_where_colmap_would_put_it() {
        // COLMAP: x_cam = R X + t, then pixel = f · x/z + c. Without distortion this must equal our projection.
        let camera = Camera::pinhole(1000, 800, 0.01, 20.0);
        let pose = Pose {
            center: Vec3::new(1.0, -10.0, 2.0),
            rotation: lineflow_photogrammetry::look_at(&Vec3::new(1.0, -10.0, 2.0), &Vec3::new(1.5, 0.0, 2.5), &Vec3::z()),
        };
        let x = Vec3::new(1.3, 0.0, 2.9);
        let ours = pose.project(&camera, &x).unwrap();
        let r = flip() * pose.rotation;
        let c = r * x - r * pose.center;
        let (p, _) = opencv_parameters(&camera);
        let colmap = [p[0] * c.x / c.z + p[2], p[1] * c.y / c.z + p[3]];
        assert!((colmap[0] - (ours[0] + 0.5)).abs() < 1e-9 && (colmap[1] - (ours[1] + 0.5)).abs() < 1e-9);
    }
}
