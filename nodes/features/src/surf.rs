//! SURF as the thesis describes it (seed 000 §2.4), with the standard values of Bay et al. where it is silent:
//! box-filter Hessian on an integral image (det = Dxx·Dyy − (0.9·Dxy)²), scale space by growing the filter
//! (9, 15, 21, 27 in the first octave, the step doubling per octave), 3×3×3 non-maximum suppression with quadratic
//! interpolation, Haar-wavelet orientation (radius 6s, wavelet 4s, Gaussian σ = 2s, sliding π/3 sector), and the
//! 64-D descriptor (window 20s, 4×4 sub-regions of 5×5 samples, wavelet 2s, Gaussian σ = 3.3s, (Σdx, Σdy, Σ|dx|,
//! Σ|dy|), unit length), with the sign of the Laplacian for matching.
//!
//! Intensities are 0..255 and responses are divided by the filter area, as in OpenCV, so the Hessian threshold
//! means the same as OpenCV's `hessianThreshold`.
use rayon::prelude::*;

use crate::integral::Integral;

/// Detector and descriptor settings.
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SurfParams {
    /// Minimum determinant of the Hessian (OpenCV's `hessianThreshold`). 100 gives about 3,500 keypoints on a
    /// full-size (12 MP) synthetic façade frame, 400 only about 260: façade texture is low in contrast.
    pub hessian_threshold: f32,
    /// Octaves of the scale space.
    pub octaves: usize,
    /// Sampling step of the first octave in pixels (1 = every pixel, 2 = OpenSURF's faster default).
    pub init_sample: usize,
    /// Keep at most this many keypoints, the strongest (0 = all).
    pub max_keypoints: usize,
    /// Skip the orientation (all keypoints point along +x): faster, for images that do not rotate.
    pub upright: bool,
}

impl Default for SurfParams {
    fn default() -> Self {
        Self {
            hessian_threshold: 100.0,
            octaves: 4,
            init_sample: 1,
            max_keypoints: 0,
            upright: false,
        }
    }
}

impl lineflow_runtime::StageParams for SurfParams {
    fn validate(&self) -> Result<(), lineflow_runtime::ParamError> {
        use lineflow_runtime::params::check;
        let threshold = self.hessian_threshold;
        check(threshold.is_finite() && threshold >= 0.0, "hessian_threshold", ">= 0", threshold)?;
        check((1..=6).contains(&self.octaves), "octaves", "in 1..=6", self.octaves)?;
        check((1..=4).contains(&self.init_sample), "init_sample", "in 1..=4", self.init_sample)
    }
}

/// Filter sizes per octave (the first octave's 9, 15, 21, 27, then 15, 27, 39, 51, ...).
const LAYERS: usize = 4;

/// The 0.9 weight of eq. (8), squared.
const DXY_WEIGHT2: f32 = 0.81;

/// A detected interest point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// Column, pixels (pixel centres at integers).
    pub col: f32,
    /// Row, pixels.
    pub row: f32,
    /// Scale s = 1.2 · L / 9 for filter size L.
    pub scale: f32,
    /// det(H) at the maximum.
    pub response: f32,
    /// Sign of the Laplacian (trace of H): +1 dark blob on bright ground... as Dxx + Dyy > 0, else −1.
    pub laplacian_sign: i32,
}

/// A described interest point.
#[derive(Debug, Clone, PartialEq)]
pub struct Feature {
    /// The detection.
    pub at: Detection,
    /// Dominant orientation, radians, counter-clockwise from +x in image coordinates (x right, y down).
    pub orientation: f32,
    /// 64-D unit descriptor.
    pub descriptor: [f32; 64],
}

fn filter_size(octave: usize, layer: usize) -> usize {
    3 * ((2 << octave) * (layer + 1) + 1)
}

/// One layer of the scale space: det(H) and trace sign on the octave's sampling grid.
struct Layer {
    size: usize,
    step: usize,
    cols: usize,
    rows: usize,
    det: Vec<f32>,
}

/// Box sums on the rows `ya..yb` between columns `x0..x1` (half-open), inside the image.
#[inline]
fn boxsum(ii: &Integral, x0: usize, y0: usize, x1: usize, y1: usize) -> f32 {
    ii.sum_inside(x0, y0, x1, y1) as f32
}

/// (Dxx, Dyy, Dxy) of filter size `size` centred on pixel (x, y), divided by the filter area. The caller keeps the
/// filter inside the image: `border(size) <= x < width - border(size)`, likewise for y.
#[inline]
fn hessian(ii: &Integral, x: usize, y: usize, size: usize) -> (f32, f32, f32) {
    let l = size / 3;
    let half = (size - 1) / 2; // (3l − 1) / 2
    let mid = (l - 1) / 2;
    // Dxx: a 3l wide, 2l−1 high box with weights +1, −2, +1 across = whole box − 3 × middle third.
    let dxx = boxsum(ii, x - half, y - (l - 1), x + half + 1, y + l) - 3.0 * boxsum(ii, x - mid, y - (l - 1), x + mid + 1, y + l);
    let dyy = boxsum(ii, x - (l - 1), y - half, x + l, y + half + 1) - 3.0 * boxsum(ii, x - (l - 1), y - mid, x + l, y + mid + 1);
    let dxy = boxsum(ii, x - l, y - l, x, y) + boxsum(ii, x + 1, y + 1, x + l + 1, y + l + 1)
        - boxsum(ii, x + 1, y - l, x + l + 1, y)
        - boxsum(ii, x - l, y + 1, x, y + l + 1);
    let inv = 1.0 / (size * size) as f32;
    (dxx * inv, dyy * inv, dxy * inv)
}

/// Pixels a filter of `size` reaches from its centre.
fn border(size: usize) -> usize {
    (size - 1) / 2 + 1
}

/// The det(H) responses of one filter size, in the memory of `det` (its old contents are cleared).
fn layer(ii: &Integral, size: usize, step: usize, mut det: Vec<f32>) -> Layer {
    let (cols, rows) = (ii.width() / step, ii.height() / step);
    let b = border(size);
    det.clear();
    det.resize(cols * rows, 0.0);
    det.par_chunks_mut(cols.max(1)).enumerate().for_each(|(r, out)| {
        let y = r * step;
        if y < b || y + b > ii.height() {
            return;
        }
        for (c, o) in out.iter_mut().enumerate() {
            let x = c * step;
            if x < b || x + b > ii.width() {
                continue;
            }
            let (dxx, dyy, dxy) = hessian(ii, x, y, size);
            *o = dxx * dyy - DXY_WEIGHT2 * dxy * dxy;
        }
    });
    Layer {
        size,
        step,
        cols,
        rows,
        det,
    }
}

/// Memory kept between frames: the integral image and the response layers (about 260 MB at 12 MP with
/// `init_sample` 1). Fresh pages of that size cost the kernel's zeroing on every frame, a fifth of SURF's time.
#[derive(Debug, Default)]
pub struct SurfScratch {
    sums: Vec<u32>,
    layers: Vec<Vec<f32>>,
}

/// Interest points: maxima of det(H) over (x, y, scale) above the threshold, interpolated.
pub fn detect(ii: &Integral, p: &SurfParams) -> Vec<Detection> {
    detect_in(ii, p, &mut Vec::new())
}

/// [`detect`] with the response layers' memory taken from and returned to `pool`.
fn detect_in(ii: &Integral, p: &SurfParams, pool: &mut Vec<Vec<f32>>) -> Vec<Detection> {
    let mut found = Vec::new();
    for octave in 0..p.octaves {
        let step = p.init_sample.max(1) << octave;
        if filter_size(octave, LAYERS - 1) + 2 * step > ii.width().min(ii.height()) {
            break;
        }
        let layers: Vec<Layer> = (0..LAYERS)
            .map(|i| layer(ii, filter_size(octave, i), step, pool.pop().unwrap_or_default()))
            .collect();
        for i in 1..LAYERS - 1 {
            let (below, here, above) = (&layers[i - 1], &layers[i], &layers[i + 1]);
            // Every neighbour must be inside the largest filter's reach.
            let margin = border(above.size).div_ceil(step) + 1;
            let rows: Vec<Vec<Detection>> = (margin..here.rows.saturating_sub(margin))
                .into_par_iter()
                .map(|r| {
                    let mut out = Vec::new();
                    for c in margin..here.cols.saturating_sub(margin) {
                        let v = here.det[r * here.cols + c];
                        if v < p.hessian_threshold || !is_maximum(v, r, c, [below, here, above]) {
                            continue;
                        }
                        if let Some(d) = interpolate(ii, r, c, [below, here, above]) {
                            out.push(d);
                        }
                    }
                    out
                })
                .collect();
            found.extend(rows.into_iter().flatten());
        }
        pool.extend(layers.into_iter().map(|l| l.det));
    }
    // Strongest first; ties broken by position so the order never depends on threads.
    found.sort_by(|a, b| {
        b.response
            .total_cmp(&a.response)
            .then(a.row.total_cmp(&b.row))
            .then(a.col.total_cmp(&b.col))
    });
    if p.max_keypoints > 0 {
        found.truncate(p.max_keypoints);
    }
    found
}

fn is_maximum(v: f32, r: usize, c: usize, layers: [&Layer; 3]) -> bool {
    for (k, l) in layers.iter().enumerate() {
        for dr in 0..3 {
            let row = &l.det[(r + dr - 1) * l.cols..];
            for dc in 0..3 {
                // On a plateau (symmetric targets, flat clipped regions) the first sample in scan order wins, so
                // exactly one of equal neighbours is a maximum.
                let n = row[c + dc - 1];
                if n > v || (n == v && (k, dr, dc) < (1, 1, 1)) {
                    return false;
                }
            }
        }
    }
    true
}

/// Fits a quadratic to the 3×3×3 neighbourhood; keeps the maximum when the fitted peak lies within one sample (as
/// OpenCV does: a peak halfway between two samples of a coarse octave is still a peak).
fn interpolate(ii: &Integral, r: usize, c: usize, layers: [&Layer; 3]) -> Option<Detection> {
    let at =
        |k: usize, dr: isize, dc: isize| layers[k].det[(r as isize + dr) as usize * layers[k].cols + (c as isize + dc) as usize] as f64;
    let v = at(1, 0, 0);
    let g = [
        (at(1, 0, 1) - at(1, 0, -1)) / 2.0,
        (at(1, 1, 0) - at(1, -1, 0)) / 2.0,
        (at(2, 0, 0) - at(0, 0, 0)) / 2.0,
    ];
    let dxx = at(1, 0, 1) + at(1, 0, -1) - 2.0 * v;
    let dyy = at(1, 1, 0) + at(1, -1, 0) - 2.0 * v;
    let dss = at(2, 0, 0) + at(0, 0, 0) - 2.0 * v;
    let dxy = (at(1, 1, 1) - at(1, 1, -1) - at(1, -1, 1) + at(1, -1, -1)) / 4.0;
    let dxs = (at(2, 0, 1) - at(2, 0, -1) - at(0, 0, 1) + at(0, 0, -1)) / 4.0;
    let dys = (at(2, 1, 0) - at(2, -1, 0) - at(0, 1, 0) + at(0, -1, 0)) / 4.0;
    let h = nalgebra::Matrix3::new(dxx, dxy, dxs, dxy, dyy, dys, dxs, dys, dss);
    let offset = -(h.try_inverse()? * nalgebra::Vector3::from(g));
    if offset.iter().any(|o| o.abs() > 1.0) {
        return None;
    }
    let (here, above) = (layers[1], layers[2]);
    let step = here.step as f64;
    let size = here.size as f64 + offset[2] * (above.size - here.size) as f64;
    let (x, y) = (c * here.step, r * here.step);
    let (dxx_, dyy_, _) = hessian(ii, x, y, here.size);
    Some(Detection {
        col: ((c as f64 + offset[0]) * step) as f32,
        row: ((r as f64 + offset[1]) * step) as f32,
        scale: (1.2 * size / 9.0) as f32,
        response: (v + 0.5 * (g[0] * offset[0] + g[1] * offset[1] + g[2] * offset[2])) as f32,
        laplacian_sign: if dxx_ + dyy_ >= 0.0 { 1 } else { -1 },
    })
}

fn gaussian(dx: f32, dy: f32, sigma: f32) -> f32 {
    (-(dx * dx + dy * dy) / (2.0 * sigma * sigma)).exp()
}

/// Dominant orientation: Haar responses (side 4s) at step s within radius 6s, Gaussian-weighted (σ = 2s), summed
/// in a sliding π/3 sector; the longest sum's direction.
pub fn orientation(ii: &Integral, d: &Detection) -> f32 {
    let s = d.scale;
    let size = (2.0 * (2.0 * s).round()).max(2.0) as isize;
    let (cx, cy) = (d.col.round() as isize, d.row.round() as isize);
    let mut samples = Vec::with_capacity(113);
    for j in -6i32..=6 {
        for i in -6i32..=6 {
            if i * i + j * j >= 36 {
                continue;
            }
            let (x, y) = (cx + (i as f32 * s).round() as isize, cy + (j as f32 * s).round() as isize);
            let w = gaussian(i as f32, j as f32, 2.0);
            let (dx, dy) = (w * ii.haar_x(x, y, size), w * ii.haar_y(x, y, size));
            if dx != 0.0 || dy != 0.0 {
                samples.push((dy.atan2(dx), dx, dy));
            }
        }
    }
    let (mut best, mut best_len) = (0.0f32, 0.0f32);
    let window = std::f32::consts::FRAC_PI_3;
    let steps = 42;
    for k in 0..steps {
        let start = -std::f32::consts::PI + k as f32 * std::f32::consts::TAU / steps as f32;
        let (mut sx, mut sy) = (0.0f32, 0.0f32);
        for &(a, dx, dy) in &samples {
            let rel = (a - start).rem_euclid(std::f32::consts::TAU);
            if rel < window {
                sx += dx;
                sy += dy;
            }
        }
        let len = sx * sx + sy * sy;
        if len > best_len {
            best_len = len;
            best = sy.atan2(sx);
        }
    }
    best
}

/// The 64-D descriptor in the frame rotated by `angle`.
pub fn descriptor(ii: &Integral, d: &Detection, angle: f32) -> [f32; 64] {
    let s = d.scale;
    let size = (2.0 * s.round()).max(2.0) as isize;
    let (sin, cos) = angle.sin_cos();
    let mut out = [0f32; 64];
    for sy in 0..4 {
        for sx in 0..4 {
            let v = &mut out[(sy * 4 + sx) * 4..][..4];
            for k in 0..5 {
                for m in 0..5 {
                    // Sample position in the keypoint's frame, units of s, centred in the 20s window.
                    let u = (sx * 5 + m) as f32 - 9.5;
                    let w = (sy * 5 + k) as f32 - 9.5;
                    let x = d.col + s * (u * cos - w * sin);
                    let y = d.row + s * (u * sin + w * cos);
                    let g = gaussian(u, w, 3.3);
                    let (hx, hy) = (
                        ii.haar_x(x.round() as isize, y.round() as isize, size),
                        ii.haar_y(x.round() as isize, y.round() as isize, size),
                    );
                    // Responses along and across the orientation.
                    let along = g * (hx * cos + hy * sin);
                    let across = g * (-hx * sin + hy * cos);
                    v[0] += along;
                    v[1] += across;
                    v[2] += along.abs();
                    v[3] += across.abs();
                }
            }
        }
    }
    let norm = out.iter().map(|v| v * v).sum::<f32>().sqrt();
    if norm > 0.0 {
        out.iter_mut().for_each(|v| *v /= norm);
    }
    out
}

/// Detects and describes the interest points of an 8-bit grey image.
pub fn surf(pixels: &[u8], width: usize, height: usize, p: &SurfParams) -> Vec<Feature> {
    surf_in(&mut SurfScratch::default(), pixels, width, height, p)
}

/// [`surf`] in the memory of `scratch`, which a stream of frames keeps from one frame to the next.
pub fn surf_in(scratch: &mut SurfScratch, pixels: &[u8], width: usize, height: usize, p: &SurfParams) -> Vec<Feature> {
    let ii = Integral::in_buffer(pixels, width, height, std::mem::take(&mut scratch.sums));
    let found = detect_in(&ii, p, &mut scratch.layers);
    let features = found
        .par_iter()
        .map(|d| {
            let orientation = if p.upright { 0.0 } else { orientation(&ii, d) };
            Feature {
                at: *d,
                orientation,
                descriptor: descriptor(&ii, d, orientation),
            }
        })
        .collect();
    scratch.sums = ii.into_buffer();
    features
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dark disc of `radius` on a bright ground.
    fn blob(w: usize, h: usize, cx: f32, cy: f32, radius: f32) -> Vec<u8> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32 - cx, (i / w) as f32 - cy);
                if x * x + y * y <= radius * radius {
                    40
                } else {
                    200
                }
            })
            .collect()
    }

    #[test]
    fn a_disc_is_found_at_its_centre_at_a_scale_that_grows_with_it() {
        let mut scales = Vec::new();
        for radius in [4.0f32, 8.0] {
            let (w, h) = (160, 160);
            let px = blob(w, h, 80.0, 77.0, radius);
            let f = surf(&px, w, h, &SurfParams::default());
            let best = f.first().expect("the disc is detected");
            assert!(
                (best.at.col - 80.0).abs() < 1.0 && (best.at.row - 77.0).abs() < 1.0,
                "{:?}",
                best.at
            );
            assert_eq!(best.at.laplacian_sign, 1, "a dark blob has a positive Laplacian");
            scales.push(best.at.scale);
        }
        assert!(scales[1] > 1.6 * scales[0], "{scales:?}");
    }

    #[test]
    fn memory_kept_between_frames_of_different_sizes_gives_what_fresh_memory_gives() {
        let mut scratch = SurfScratch::default();
        let same =
            |a: &[Feature], b: &[Feature]| a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.at == y.at && x.descriptor == y.descriptor);
        // A large frame first, so that the smaller ones inherit longer buffers full of its responses.
        for (w, h, r) in [(240, 200, 9.0), (160, 120, 5.0), (200, 160, 7.0)] {
            let px = blob(w, h, w as f32 / 2.0, h as f32 / 2.0 - 3.0, r);
            let kept = surf_in(&mut scratch, &px, w, h, &SurfParams::default());
            assert!(!kept.is_empty());
            assert!(same(&kept, &surf(&px, w, h, &SurfParams::default())), "{w}x{h}");
        }
    }

    /// A textured patch: repeatability under rotation is the point of the orientation.
    fn texture(w: usize, h: usize, angle: f32) -> Vec<u8> {
        let (sin, cos) = angle.sin_cos();
        let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32 - cx, (i / w) as f32 - cy);
                // Rotate the sampling point back into the pattern's frame.
                let (u, v) = (cos * x + sin * y, -sin * x + cos * y);
                // Elongated blobs: an isotropic blob has no dominant direction to follow.
                let blobs = [
                    (-20.0, -10.0, 6.0, 60.0),
                    (15.0, 12.0, 9.0, 230.0),
                    (5.0, -25.0, 4.0, 20.0),
                    (-18.0, 22.0, 7.0, 180.0),
                ];
                let mut val = 128.0f32;
                for (bx, by, r, level) in blobs {
                    let (du, dv) = (u - bx, v - by);
                    let d2 = du * du + 6.0 * dv * dv + 2.0 * du * dv;
                    val += (level - 128.0) * (-d2 / (2.0 * r * r)).exp();
                }
                val.clamp(0.0, 255.0) as u8
            })
            .collect()
    }

    #[test]
    fn orientation_and_descriptor_follow_a_rotation() {
        let (w, h) = (200, 200);
        let p = SurfParams {
            hessian_threshold: 50.0,
            ..Default::default()
        };
        let a = surf(&texture(w, h, 0.0), w, h, &p);
        let b = surf(&texture(w, h, 0.6), w, h, &p);
        let (sin, cos) = 0.6f32.sin_cos();
        let mut found = 0;
        for fa in a.iter().take(4) {
            // Where the rotation takes this point, and what was detected there.
            let (x, y) = (fa.at.col - 100.0, fa.at.row - 100.0);
            let (ex, ey) = (cos * x - sin * y + 100.0, sin * x + cos * y + 100.0);
            let Some(fb) = b.iter().find(|f| (f.at.col - ex).hypot(f.at.row - ey) < 2.0) else {
                continue;
            };
            found += 1;
            let turn =
                (fb.orientation - fa.orientation - 0.6 + std::f32::consts::PI).rem_euclid(std::f32::consts::TAU) - std::f32::consts::PI;
            assert!(turn.abs() < 0.15, "orientation follows the rotation: off by {turn}");
            let dist = fa
                .descriptor
                .iter()
                .zip(&fb.descriptor)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f32>()
                .sqrt();
            assert!(dist < 0.25, "descriptor distance {dist} between a point and its rotated self");
            assert!((fb.at.scale / fa.at.scale - 1.0).abs() < 0.1);
        }
        assert!(found >= 3, "only {found} of the strongest 4 found again after the rotation");
    }

    #[test]
    fn the_result_is_the_same_on_any_number_of_threads() {
        let (w, h) = (200, 200);
        let px = texture(w, h, 0.3);
        let p = SurfParams {
            hessian_threshold: 50.0,
            ..Default::default()
        };
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| surf(&px, w, h, &p));
        assert_eq!(one, surf(&px, w, h, &p));
    }
}
