//! Least-squares matching (LSM): the sub-pixel refinement of a tie point's position in one image against a
//! template around its position in another.
//!
//! SURF places a keypoint at the centre of a blob found at its scale, which moves by a good part of a pixel between
//! views of the same point (the blob's shape changes with perspective, and at 12 MP the blobs are several pixels
//! wide). A bundle adjustment can do no better than its observations, so every observation of a track is matched
//! to the track's first one, its anchor: the template is the anchor image's neighbourhood, mapped into the other
//! image by the local affine transfer of the façade plane, and the shift (with a radiometric gain and offset) that
//! minimises the squared grey-value differences is found by Gauss-Newton. All observations of a track then refer
//! to the same object point, the one imaged at the anchor's position.

/// An 8-bit grey image, row-major.
#[derive(Debug, Clone)]
pub struct Gray {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `width × height` grey values.
    pub data: Vec<u8>,
}

impl Gray {
    /// Bilinear grey value and its gradient at (x, y), none within one pixel of the border.
    #[inline]
    fn sample(&self, x: f64, y: f64) -> Option<(f64, [f64; 2])> {
        if !(x >= 1.0 && y >= 1.0) {
            return None;
        }
        let (c, r) = (x as usize, y as usize);
        if c + 2 >= self.width || r + 2 >= self.height {
            return None;
        }
        let (fx, fy) = (x - c as f64, y - r as f64);
        let i = r * self.width + c;
        let d = &self.data;
        let (a, b, e, f) = (d[i] as f64, d[i + 1] as f64, d[i + self.width] as f64, d[i + self.width + 1] as f64);
        let top = a + fx * (b - a);
        let bottom = e + fx * (f - e);
        let value = top + fy * (bottom - top);
        let gx = (b - a) + fy * ((f - e) - (b - a));
        let gy = bottom - top;
        Some((value, [gx, gy]))
    }
}

/// LSM settings.
#[derive(Debug, Clone, Copy)]
pub struct LsmParams {
    /// Half the template's side, pixels (the template is (2h+1)² pixels).
    pub half_window: usize,
    /// Gauss-Newton iterations at most.
    pub iterations: usize,
    /// Largest accepted move from the starting position, pixels: beyond it the match is not the same point.
    pub max_shift_px: f64,
    /// Smallest accepted correlation between the template and the matched window.
    pub min_correlation: f64,
    /// Largest accepted standard deviation of the refined position, pixels (low texture gives a poor fix).
    pub max_sigma_px: f64,
}

impl Default for LsmParams {
    fn default() -> Self {
        Self {
            half_window: 8,
            iterations: 12,
            max_shift_px: 2.0,
            min_correlation: 0.8,
            max_sigma_px: 0.1,
        }
    }
}

/// A refined position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refined {
    /// Position in the target image, pixels.
    pub px: [f64; 2],
    /// Correlation between the template and the matched window.
    pub correlation: f64,
    /// Standard deviation of the position (the larger axis), pixels.
    pub sigma_px: f64,
}

/// The position in `target` of the point at `anchor_px` in `anchor`, starting from `start_px`. `affine` maps a
/// small offset around the anchor into the target image (the local Jacobian of the transfer between the images).
/// None when the template leaves either image, the fit diverges or fails a quality test of `params`.
pub fn refine(
    anchor: &Gray,
    anchor_px: [f64; 2],
    target: &Gray,
    start_px: [f64; 2],
    affine: [[f64; 2]; 2],
    params: &LsmParams,
) -> Option<Refined> {
    let h = params.half_window as isize;
    let grid: Vec<[f64; 2]> = (-h..=h).flat_map(|r| (-h..=h).map(move |c| [c as f64, r as f64])).collect();
    // The template's pixels in the anchor image, and where the affine transfer puts them around the target point.
    let template: Vec<f64> = grid
        .iter()
        .map(|[c, r]| anchor.sample(anchor_px[0] + c, anchor_px[1] + r).map(|(v, _)| v))
        .collect::<Option<_>>()?;
    let offsets: Vec<[f64; 2]> = grid
        .iter()
        .map(|[c, r]| [affine[0][0] * c + affine[0][1] * r, affine[1][0] * c + affine[1][1] * r])
        .collect();
    let mean_t = template.iter().sum::<f64>() / template.len() as f64;
    let var_t = template.iter().map(|v| (v - mean_t).powi(2)).sum::<f64>();
    if var_t <= 1e-9 {
        return None;
    }
    // Unknowns: the shift (x, y), the offset r0 and the gain r1 of `template ≈ r0 + r1 · target`.
    let (mut p, mut r0, mut r1) = (start_px, 0.0f64, 1.0f64);
    let mut values = vec![0.0; offsets.len()];
    for _ in 0..params.iterations {
        let mut n = nalgebra::Matrix4::<f64>::zeros();
        let mut b = nalgebra::Vector4::<f64>::zeros();
        let mut sum_e2 = 0.0;
        for ((o, t), value) in offsets.iter().zip(&template).zip(values.iter_mut()) {
            let (v, g) = target.sample(p[0] + o[0], p[1] + o[1])?;
            *value = v;
            let e = t - (r0 + r1 * v);
            let a = nalgebra::Vector4::new(r1 * g[0], r1 * g[1], 1.0, v);
            n += a * a.transpose();
            b += a * e;
            sum_e2 += e * e;
        }
        let inverse = n.try_inverse()?;
        let dx = inverse * b;
        p = [p[0] + dx[0], p[1] + dx[1]];
        r0 += dx[2];
        r1 += dx[3];
        let moved = (p[0] - start_px[0]).hypot(p[1] - start_px[1]);
        // NaN fails both tests.
        if !(moved <= params.max_shift_px && r1 > 0.0) {
            return None;
        }
        if dx[0].hypot(dx[1]) < 1e-3 {
            let redundancy = (offsets.len() - 4) as f64;
            let s0 = (sum_e2 / redundancy).sqrt();
            let sigma_px = s0 * inverse[(0, 0)].max(inverse[(1, 1)]).sqrt();
            let correlation = correlation(&template, mean_t, var_t, &values);
            let good = correlation >= params.min_correlation && sigma_px <= params.max_sigma_px;
            return good.then_some(Refined {
                px: p,
                correlation,
                sigma_px,
            });
        }
    }
    None
}

fn correlation(template: &[f64], mean_t: f64, var_t: f64, values: &[f64]) -> f64 {
    let mean_v = values.iter().sum::<f64>() / values.len() as f64;
    let (mut cov, mut var_v) = (0.0, 0.0);
    for (t, v) in template.iter().zip(values) {
        cov += (t - mean_t) * (v - mean_v);
        var_v += (v - mean_v).powi(2);
    }
    if var_v <= 1e-9 {
        return 0.0;
    }
    cov / (var_t * var_v).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth, textured image: the sum of a few sinusoids, so that bilinear resampling is close to exact.
    fn texture(width: usize, height: usize, shift: [f64; 2], gain: f64, offset: f64) -> Gray {
        let f = |x: f64, y: f64| {
            120.0 + 40.0 * (0.31 * x + 0.17 * y).sin() + 30.0 * (0.23 * y - 0.11 * x).cos() + 20.0 * (0.07 * x * 0.9 + 0.29 * y).sin()
        };
        let data = (0..height)
            .flat_map(|r| (0..width).map(move |c| (c, r)))
            .map(|(c, r)| {
                (offset + gain * f(c as f64 - shift[0], r as f64 - shift[1]))
                    .round()
                    .clamp(0.0, 255.0) as u8
            })
            .collect();
        Gray { width, height, data }
    }

    #[test]
    fn a_shift_and_a_change_of_brightness_are_recovered_to_a_twentieth_of_a_pixel() {
        let anchor = texture(64, 64, [0.0, 0.0], 1.0, 0.0);
        let target = texture(64, 64, [3.37, -1.62], 0.8, 20.0);
        let identity = [[1.0, 0.0], [0.0, 1.0]];
        let r = refine(&anchor, [30.0, 31.0], &target, [33.0, 29.0], identity, &LsmParams::default()).expect("converges");
        assert!((r.px[0] - 33.37).abs() < 0.05 && (r.px[1] - 29.38).abs() < 0.05, "{r:?}");
        assert!(r.correlation > 0.99, "{r:?}");
    }

    #[test]
    fn a_start_beyond_the_pull_in_range_or_a_flat_image_gives_none() {
        let anchor = texture(64, 64, [0.0, 0.0], 1.0, 0.0);
        let flat = Gray {
            width: 64,
            height: 64,
            data: vec![90; 64 * 64],
        };
        let identity = [[1.0, 0.0], [0.0, 1.0]];
        assert!(refine(&anchor, [30.0, 31.0], &flat, [30.0, 31.0], identity, &LsmParams::default()).is_none());
        assert!(refine(&flat, [30.0, 31.0], &anchor, [30.0, 31.0], identity, &LsmParams::default()).is_none());
        // Near the border the template does not fit.
        assert!(refine(&anchor, [3.0, 31.0], &anchor, [3.0, 31.0], identity, &LsmParams::default()).is_none());
    }
}
