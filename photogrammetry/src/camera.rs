//! The interior orientation of `conventions.md`: pixel ↔ photo coordinates and the correction model.

/// One camera: image size, pixel pitch, principal distance, principal point and the correction model.
///
/// Lengths are millimetres; `radial` is (k1, k2, k3) in mm⁻², mm⁻⁴, mm⁻⁶ and `decentering` (p1, p2) in mm⁻¹.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixel pitch, mm.
    pub pixel_size_mm: f64,
    /// Principal distance f, mm.
    pub focal_mm: f64,
    /// Principal point (x0, y0) in photo coordinates, mm.
    pub principal_point_mm: [f64; 2],
    /// k1, k2, k3.
    pub radial: [f64; 3],
    /// p1, p2.
    pub decentering: [f64; 2],
}

/// Tolerance of the inverse correction, mm (`conventions.md` asks for 1e-6 mm).
const INVERSE_TOL_MM: f64 = 1e-9;
const INVERSE_MAX_ITER: usize = 20;

impl Camera {
    /// Photo coordinates (mm, origin at the image centre, y up) of a pixel position (centres at integers).
    #[inline]
    pub fn pixel_to_photo(&self, px: [f64; 2]) -> [f64; 2] {
        [
            (px[0] - (self.width as f64 - 1.0) / 2.0) * self.pixel_size_mm,
            ((self.height as f64 - 1.0) / 2.0 - px[1]) * self.pixel_size_mm,
        ]
    }

    /// Pixel position of photo coordinates.
    #[inline]
    pub fn photo_to_pixel(&self, photo: [f64; 2]) -> [f64; 2] {
        [
            photo[0] / self.pixel_size_mm + (self.width as f64 - 1.0) / 2.0,
            (self.height as f64 - 1.0) / 2.0 - photo[1] / self.pixel_size_mm,
        ]
    }

    /// The ideal point, relative to the principal point, of a measured photo point: `(xb + Δx, yb + Δy)`.
    pub fn correct(&self, measured: [f64; 2]) -> [f64; 2] {
        // Every rendered pixel goes through here, so no Jacobian.
        let [k1, k2, k3] = self.radial;
        let [p1, p2] = self.decentering;
        let xb = measured[0] - self.principal_point_mm[0];
        let yb = measured[1] - self.principal_point_mm[1];
        let r2 = xb * xb + yb * yb;
        let k = r2 * (k1 + r2 * (k2 + r2 * k3));
        [
            xb * (1.0 + k) + p1 * (r2 + 2.0 * xb * xb) + 2.0 * p2 * xb * yb,
            yb * (1.0 + k) + p2 * (r2 + 2.0 * yb * yb) + 2.0 * p1 * xb * yb,
        ]
    }

    /// The correction and its Jacobian with respect to the measured point.
    fn correct_with_jacobian(&self, measured: [f64; 2]) -> ([f64; 2], [[f64; 2]; 2]) {
        let [k1, k2, k3] = self.radial;
        let [p1, p2] = self.decentering;
        let xb = measured[0] - self.principal_point_mm[0];
        let yb = measured[1] - self.principal_point_mm[1];
        let r2 = xb * xb + yb * yb;
        let k = r2 * (k1 + r2 * (k2 + r2 * k3));
        let dk = 2.0 * k1 + r2 * (4.0 * k2 + 6.0 * k3 * r2);
        let fx = xb * (1.0 + k) + p1 * (r2 + 2.0 * xb * xb) + 2.0 * p2 * xb * yb;
        let fy = yb * (1.0 + k) + p2 * (r2 + 2.0 * yb * yb) + 2.0 * p1 * xb * yb;
        let jxy = dk * xb * yb + 2.0 * p1 * yb + 2.0 * p2 * xb;
        let jac = [
            [1.0 + k + dk * xb * xb + 6.0 * p1 * xb + 2.0 * p2 * yb, jxy],
            [jxy, 1.0 + k + dk * yb * yb + 6.0 * p2 * yb + 2.0 * p1 * xb],
        ];
        ([fx, fy], jac)
    }

    /// The measured photo point whose correction is `ideal` (relative to the principal point), by Newton's method.
    ///
    /// Returns `None` where the model does not invert (far outside the image, where the polynomial folds over).
    pub fn distort(&self, ideal: [f64; 2]) -> Option<[f64; 2]> {
        let mut m = [ideal[0] + self.principal_point_mm[0], ideal[1] + self.principal_point_mm[1]];
        for _ in 0..INVERSE_MAX_ITER {
            let (f, j) = self.correct_with_jacobian(m);
            let (ex, ey) = (f[0] - ideal[0], f[1] - ideal[1]);
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            if det.abs() < 1e-12 || !det.is_finite() {
                return None;
            }
            let dx = (j[1][1] * ex - j[0][1] * ey) / det;
            let dy = (j[0][0] * ey - j[1][0] * ex) / det;
            m[0] -= dx;
            m[1] -= dy;
            if dx.abs().max(dy.abs()) < INVERSE_TOL_MM {
                // Beyond the fold of a pincushion correction the polynomial has a second, meaningless root.
                let (_, j) = self.correct_with_jacobian(m);
                return (j[0][0] * j[1][1] - j[0][1] * j[1][0] > 0.0).then_some(m);
            }
        }
        None
    }

    /// The ideal photo point (relative to the principal point) of a measured pixel position.
    #[inline]
    pub fn pixel_to_ideal(&self, px: [f64; 2]) -> [f64; 2] {
        self.correct(self.pixel_to_photo(px))
    }

    /// The measured pixel position of an ideal photo point (relative to the principal point).
    pub fn ideal_to_pixel(&self, ideal: [f64; 2]) -> Option<[f64; 2]> {
        self.distort(ideal).map(|m| self.photo_to_pixel(m))
    }

    /// The ground sample distance in metres at `distance_m` from the camera.
    pub fn gsd_m(&self, distance_m: f64) -> f64 {
        distance_m * self.pixel_size_mm / self.focal_mm
    }

    /// A distortion-free camera with the principal point at the image centre (synthetic scenes, tests).
    pub fn pinhole(width: u32, height: u32, pixel_size_mm: f64, focal_mm: f64) -> Camera {
        Camera {
            width,
            height,
            pixel_size_mm,
            focal_mm,
            principal_point_mm: [0.0; 2],
            radial: [0.0; 3],
            decentering: [0.0; 2],
        }
    }

    /// The camera of a resampled sensor: `scale` times the pixels in each direction over the same field of view.
    pub fn scaled(&self, scale: f64) -> Camera {
        let width = ((self.width as f64 * scale).round() as u32).max(2);
        let height = ((self.height as f64 * scale).round() as u32).max(2);
        Camera {
            width,
            height,
            pixel_size_mm: self.pixel_size_mm * self.width as f64 / width as f64,
            ..*self
        }
    }

    /// Whether a pixel position lies inside the image (with `margin` pixels to spare).
    pub fn contains(&self, px: [f64; 2], margin: f64) -> bool {
        px[0] >= -0.5 + margin
            && px[1] >= -0.5 + margin
            && px[0] <= self.width as f64 - 0.5 - margin
            && px[1] <= self.height as f64 - 0.5 - margin
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn a55() -> Camera {
        Camera {
            width: 4912,
            height: 3264,
            pixel_size_mm: 0.0048,
            focal_mm: 18.007,
            principal_point_mm: [-0.229, 0.1067],
            radial: [1.74e-4, -2.0e-7, 0.0],
            decentering: [6e-6, -4e-6],
        }
    }

    #[test]
    fn pixel_photo_round_trip_and_centre() {
        let c = a55();
        assert_eq!(c.pixel_to_photo([2455.5, 1631.5]), [0.0, 0.0]);
        let p = c.pixel_to_photo([0.0, 0.0]);
        assert!(p[0] < 0.0 && p[1] > 0.0, "top-left is left and up");
        let back = c.photo_to_pixel(p);
        assert!((back[0]).abs() < 1e-9 && back[1].abs() < 1e-9);
    }

    #[test]
    fn distortion_inverts_to_a_micron_of_a_micron_everywhere() {
        let c = a55();
        let mut worst: f64 = 0.0;
        for i in 0..=40 {
            for j in 0..=40 {
                let px = [i as f64 * (c.width - 1) as f64 / 40.0, j as f64 * (c.height - 1) as f64 / 40.0];
                let measured = c.pixel_to_photo(px);
                let ideal = c.correct(measured);
                let again = c.distort(ideal).expect("inverts inside the frame");
                worst = worst.max((again[0] - measured[0]).abs()).max((again[1] - measured[1]).abs());
            }
        }
        assert!(worst < 1e-6, "round trip error {worst} mm");
    }

    #[test]
    fn corner_distortion_has_the_expected_size() {
        let c = Camera {
            radial: [1.74e-4, 0.0, 0.0],
            decentering: [0.0, 0.0],
            principal_point_mm: [0.0, 0.0],
            ..a55()
        };
        let corner = c.pixel_to_photo([0.0, 0.0]);
        let ideal = c.correct(corner);
        let shift = ((ideal[0] - corner[0]).powi(2) + (ideal[1] - corner[1]).powi(2)).sqrt();
        let r: f64 = (corner[0].powi(2) + corner[1].powi(2)).sqrt();
        assert!((shift - 1.74e-4 * r.powi(3)).abs() < 1e-12);
        assert!(shift > 0.45 && shift < 0.55, "{shift} mm");
    }

    #[test]
    fn scaling_keeps_the_field_of_view() {
        let c = a55();
        let s = c.scaled(0.13);
        assert_eq!((s.width, s.height), (639, 424));
        let fov = |c: &Camera| c.width as f64 * c.pixel_size_mm;
        assert!((fov(&s) - fov(&c)).abs() < 1e-9);
    }
}
