//! OpenCV's lens model (which COLMAP's and Metashape's follow, with small differences their readers handle) and its
//! conversion to and from this project's correction model (`conventions.md`). The two models are inverse to each
//! other (OpenCV distorts ideal points, ours corrects measured ones), so no set of coefficients converts exactly:
//! the coefficients are fitted by least squares over a grid spanning the frame, and the fit's residual is reported.
use nalgebra::{DMatrix, DVector};

use crate::Camera;

/// OpenCV's pinhole camera with Brown–Conrady distortion (the rational k4–k6 included): pixel units, pixel centres at
/// integers, y down.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OpenCvLens {
    /// Focal lengths, pixels.
    pub fx: f64,
    /// .
    pub fy: f64,
    /// Principal point, pixels.
    pub cx: f64,
    /// .
    pub cy: f64,
    /// k1, k2, k3 (numerator) and k4, k5, k6 (denominator of the rational model; zero for the plain model).
    pub k: [f64; 6],
    /// p1, p2.
    pub p: [f64; 2],
}

/// How closely a converted model reproduces the original over the frame, pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitResidual {
    /// Root mean square over the grid.
    pub rms_px: f64,
    /// Largest.
    pub max_px: f64,
}

impl std::fmt::Display for FitResidual {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:.4} px RMS, {:.4} px at most", self.rms_px, self.max_px)
    }
}

/// Grid of the fits: nodes across and down the frame, corners included.
const GRID: (usize, usize) = (41, 31);

impl OpenCvLens {
    /// The distorted normalised point of an ideal normalised one (y down).
    pub fn distort(&self, q: [f64; 2]) -> [f64; 2] {
        let [x, y] = q;
        let [k1, k2, k3, k4, k5, k6] = self.k;
        let [p1, p2] = self.p;
        let r2 = x * x + y * y;
        let radial = (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1.0 + r2 * (k4 + r2 * (k5 + r2 * k6)));
        [
            x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
        ]
    }

    /// The ideal normalised point whose distortion is `d`, by Newton's method on a numerical Jacobian; `None` where
    /// it does not converge (beyond the model's valid field).
    pub fn undistort(&self, d: [f64; 2]) -> Option<[f64; 2]> {
        let mut q = d;
        for _ in 0..50 {
            let f = self.distort(q);
            let (ex, ey) = (f[0] - d[0], f[1] - d[1]);
            if ex.hypot(ey) < 1e-13 {
                return Some(q);
            }
            let h = 1e-7;
            let fx = self.distort([q[0] + h, q[1]]);
            let fy = self.distort([q[0], q[1] + h]);
            let j = [[(fx[0] - f[0]) / h, (fy[0] - f[0]) / h], [(fx[1] - f[1]) / h, (fy[1] - f[1]) / h]];
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            if !det.is_finite() || det.abs() < 1e-12 {
                return None;
            }
            q = [
                q[0] - (j[1][1] * ex - j[0][1] * ey) / det,
                q[1] - (-j[1][0] * ex + j[0][0] * ey) / det,
            ];
        }
        None
    }

    /// The pixel of an ideal normalised point.
    pub fn pixel_of(&self, q: [f64; 2]) -> [f64; 2] {
        let d = self.distort(q);
        [self.fx * d[0] + self.cx, self.fy * d[1] + self.cy]
    }
}

/// The pixels of the fitting grid.
fn grid(width: u32, height: u32) -> impl Iterator<Item = [f64; 2]> {
    let (w, h) = ((width.max(2) - 1) as f64, (height.max(2) - 1) as f64);
    (0..GRID.1).flat_map(move |j| (0..GRID.0).map(move |i| [w * i as f64 / (GRID.0 - 1) as f64, h * j as f64 / (GRID.1 - 1) as f64]))
}

/// Least squares with the columns scaled to unit norm (powers of r span many orders of magnitude). A coefficient
/// that moves no point by a millionth of a pixel (`pixel`, in the rows' unit) is the fit's rounding noise, and is
/// written as the zero it is.
fn solve(rows: &[[f64; 5]], rhs: &[f64], pixel: f64) -> Option<[f64; 5]> {
    // An SVD of non-finite values does not converge (and nalgebra's `svd` would try for ever).
    if !rows.iter().flatten().chain(rhs).all(|v| v.is_finite()) {
        return None;
    }
    let a = DMatrix::from_fn(rows.len(), 5, |r, c| rows[r][c]);
    let scale: Vec<f64> = (0..5).map(|c| a.column(c).norm().max(1e-300)).collect();
    let reach: Vec<f64> = (0..5).map(|c| a.column(c).amax()).collect();
    let a = DMatrix::from_fn(rows.len(), 5, |r, c| rows[r][c] / scale[c]);
    let x = a
        .try_svd(true, true, f64::EPSILON, 10_000)?
        .solve(&DVector::from_column_slice(rhs), 1e-12)
        .ok()?;
    let out = [0, 1, 2, 3, 4].map(|c| x[c] / scale[c]);
    let out = [0, 1, 2, 3, 4].map(|c| if (out[c] * reach[c]).abs() < 1e-6 * pixel { 0.0 } else { out[c] });
    out.iter().all(|v| v.is_finite()).then_some(out)
}

fn residual(errors: impl Iterator<Item = f64>) -> FitResidual {
    let (mut sum, mut n, mut max) = (0.0, 0usize, 0.0f64);
    for e in errors {
        sum += e * e;
        n += 1;
        max = max.max(e);
    }
    FitResidual {
        rms_px: (sum / n.max(1) as f64).sqrt(),
        max_px: max,
    }
}

/// This project's camera closest to an OpenCV lens on a `width × height` sensor of `pixel_size_mm` pixels: principal
/// distance from the mean of fx and fy, the principal point as is, (k1, k2, k3, p1, p2) fitted over the frame. The
/// residual compares the ideal points of both models at every grid pixel. `None` when the lens does not invert over
/// the frame.
pub fn camera_from_opencv(lens: &OpenCvLens, width: u32, height: u32, pixel_size_mm: f64) -> Option<(Camera, FitResidual)> {
    let f_px = (lens.fx + lens.fy) / 2.0;
    let mut camera = Camera {
        width,
        height,
        pixel_size_mm,
        focal_mm: f_px * pixel_size_mm,
        principal_point_mm: [0.0; 2],
        radial: [0.0; 3],
        decentering: [0.0; 2],
    };
    let pp = camera.pixel_to_photo([lens.cx, lens.cy]);
    camera.principal_point_mm = pp;
    // The ideal point (mm, relative to the principal point, y up) OpenCV gives each grid pixel.
    let ideal_of = |px: [f64; 2]| {
        let q = lens.undistort([(px[0] - lens.cx) / lens.fx, (px[1] - lens.cy) / lens.fy])?;
        Some([camera.focal_mm * q[0], -camera.focal_mm * q[1]])
    };
    let samples: Vec<([f64; 2], [f64; 2])> = grid(width, height).map(|px| Some((px, ideal_of(px)?))).collect::<Option<_>>()?;
    let (mut rows, mut rhs) = (Vec::new(), Vec::new());
    for (px, ideal) in &samples {
        let photo = camera.pixel_to_photo(*px);
        let (xb, yb) = (photo[0] - pp[0], photo[1] - pp[1]);
        let r2 = xb * xb + yb * yb;
        rows.push([xb * r2, xb * r2 * r2, xb * r2 * r2 * r2, r2 + 2.0 * xb * xb, 2.0 * xb * yb]);
        rhs.push(ideal[0] - xb);
        rows.push([yb * r2, yb * r2 * r2, yb * r2 * r2 * r2, 2.0 * xb * yb, r2 + 2.0 * yb * yb]);
        rhs.push(ideal[1] - yb);
    }
    let [k1, k2, k3, p1, p2] = solve(&rows, &rhs, pixel_size_mm)?;
    camera.radial = [k1, k2, k3];
    camera.decentering = [p1, p2];
    let fit = residual(samples.iter().map(|(px, ideal)| {
        let ours = camera.pixel_to_ideal(*px);
        (ours[0] - ideal[0]).hypot(ours[1] - ideal[1]) / pixel_size_mm
    }));
    Some((camera, fit))
}

/// The OpenCV lens closest to this project's camera: fx = fy from the principal distance, (k1, k2, k3, p1, p2)
/// fitted over the frame. The residual compares the pixel each model projects every grid pixel's ideal point to.
pub fn opencv_from_camera(camera: &Camera) -> Option<(OpenCvLens, FitResidual)> {
    let f_px = camera.focal_mm / camera.pixel_size_mm;
    let c = camera.photo_to_pixel(camera.principal_point_mm);
    let mut lens = OpenCvLens {
        fx: f_px,
        fy: f_px,
        cx: c[0],
        cy: c[1],
        k: [0.0; 6],
        p: [0.0; 2],
    };
    // Each grid pixel and its ideal normalised point under this project's model.
    let samples: Vec<([f64; 2], [f64; 2])> = grid(camera.width, camera.height)
        .map(|px| {
            let ideal = camera.pixel_to_ideal(px);
            (px, [ideal[0] / camera.focal_mm, -ideal[1] / camera.focal_mm])
        })
        .collect();
    let (mut rows, mut rhs) = (Vec::new(), Vec::new());
    for (px, [x, y]) in &samples {
        let (xd, yd) = ((px[0] - lens.cx) / f_px, (px[1] - lens.cy) / f_px);
        let r2 = x * x + y * y;
        rows.push([x * r2, x * r2 * r2, x * r2 * r2 * r2, 2.0 * x * y, r2 + 2.0 * x * x]);
        rhs.push(xd - x);
        rows.push([y * r2, y * r2 * r2, y * r2 * r2 * r2, r2 + 2.0 * y * y, 2.0 * x * y]);
        rhs.push(yd - y);
    }
    let [k1, k2, k3, p1, p2] = solve(&rows, &rhs, 1.0 / f_px)?;
    lens.k = [k1, k2, k3, 0.0, 0.0, 0.0];
    lens.p = [p1, p2];
    let fit = residual(samples.iter().map(|(px, q)| {
        let back = lens.pixel_of(*q);
        (back[0] - px[0]).hypot(back[1] - px[1])
    }));
    Some((lens, fit))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A wide-angle lens with strong barrel distortion and some decentering, as OpenCV's calibration reports one.
    fn lens() -> OpenCvLens {
        OpenCvLens {
            fx: 3000.0,
            fy: 3000.0,
            cx: 2010.5,
            cy: 1490.0,
            k: [-0.12, 0.09, -0.02, 0.0, 0.0, 0.0],
            p: [4e-4, -2e-4],
        }
    }

    #[test]
    fn undistort_inverts_distort() {
        let l = lens();
        for q in [[0.0, 0.0], [0.3, -0.2], [-0.6, 0.45]] {
            let back = l.undistort(l.distort(q)).unwrap();
            assert!((back[0] - q[0]).hypot(back[1] - q[1]) < 1e-12, "{q:?} -> {back:?}");
        }
    }

    #[test]
    fn an_opencv_lens_converts_to_our_model_within_a_small_fraction_of_a_pixel() {
        let l = lens();
        let (camera, fit) = camera_from_opencv(&l, 4000, 3000, 0.0015).unwrap();
        // 9 % of barrel distortion in the corners: three radial terms of the inverse model follow it to a tenth of a
        // pixel over most of the frame, half a pixel in the far corners.
        assert!(fit.rms_px < 0.1 && fit.max_px < 0.7, "{fit}");
        // The same ray from both models through a pixel near a corner.
        let px = [150.0, 2800.0];
        let q = l.undistort([(px[0] - l.cx) / l.fx, (px[1] - l.cy) / l.fy]).unwrap();
        let ideal = camera.pixel_to_ideal(px);
        let ours = [ideal[0] / camera.focal_mm, -ideal[1] / camera.focal_mm];
        assert!((ours[0] - q[0]).hypot(ours[1] - q[1]) * l.fx < 0.3);
        // And back: our model to OpenCV's reproduces the lens.
        let (again, back) = opencv_from_camera(&camera).unwrap();
        assert!(back.rms_px < 0.1, "{back}");
        assert!((again.cx - l.cx).abs() < 1e-9 && (again.cy - l.cy).abs() < 1e-9);
    }

    #[test]
    fn a_distortion_free_lens_gives_a_distortion_free_camera() {
        let l = OpenCvLens {
            k: [0.0; 6],
            p: [0.0; 2],
            ..lens()
        };
        let (camera, fit) = camera_from_opencv(&l, 4000, 3000, 0.0015).unwrap();
        assert!(fit.max_px < 1e-9, "{fit}");
        assert!(camera.radial.iter().chain(&camera.decentering).all(|v| v.abs() < 1e-15));
        assert!((camera.focal_mm - 4.5).abs() < 1e-12);
        // cx 2010.5 is 11 px right of the centre (1999.5); cy 1490 is 9.5 px above it (1499.5).
        assert!((camera.principal_point_mm[0] - 11.0 * 0.0015).abs() < 1e-12);
        assert!((camera.principal_point_mm[1] - 9.5 * 0.0015).abs() < 1e-12);
    }
}
