//! ORB-style binary features (Rublee et al. 2011), the second `features` implementation: FAST-9 corners on a scale
//! pyramid, ranked by the Harris response, oriented by the intensity centroid, and described by 256 grey-level
//! comparisons of 7 × 7 means in a patch steered by that orientation.
//!
//! The comparison pattern is drawn once from an isotropic Gaussian (BRIEF's pattern G II, σ = patch / 5) by a fixed
//! generator, not OpenCV's learned rBRIEF table: descriptors are therefore not interchangeable with OpenCV's.
use lineflow_runtime::params::{self, ParamError};
use rayon::prelude::*;
use serde::Deserialize;

use crate::integral::Integral;

/// Settings of [`orb`].
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OrbParams {
    /// Keypoints kept per image, the strongest, shared among the levels by their area.
    pub max_keypoints: usize,
    /// Pyramid levels.
    pub levels: usize,
    /// Scale between consecutive levels.
    pub scale_factor: f32,
    /// FAST threshold, grey levels: a corner's arc must be this much brighter or darker than its centre.
    pub fast_threshold: u8,
}

impl Default for OrbParams {
    fn default() -> Self {
        Self {
            max_keypoints: 5000,
            levels: 8,
            scale_factor: 1.2,
            fast_threshold: 20,
        }
    }
}

impl lineflow_runtime::StageParams for OrbParams {
    fn validate(&self) -> Result<(), ParamError> {
        params::at_least("max_keypoints", self.max_keypoints, 1)?;
        params::check((1..=12).contains(&self.levels), "levels", "in 1..=12", self.levels)?;
        let scale = self.scale_factor;
        params::check(scale > 1.0 && scale <= 2.0, "scale_factor", "in (1, 2]", scale)?;
        params::check(self.fast_threshold >= 1, "fast_threshold", ">= 1", self.fast_threshold)
    }
}

/// A described ORB keypoint, in the pixel coordinates of the full image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbFeature {
    /// Column.
    pub col: f32,
    /// Row.
    pub row: f32,
    /// Radius of the described patch in full-image pixels.
    pub scale_px: f32,
    /// Orientation, radians.
    pub orientation: f32,
    /// Harris response at the keypoint's level.
    pub response: f32,
    /// 256 comparisons, bit `k` of byte `k / 8` is test `k`.
    pub descriptor: [u8; 32],
}

/// Radius of the oriented patch, pixels of its level (the 31 × 31 patch of ORB).
const PATCH_RADIUS: i32 = 15;
/// Keypoints closer than this to a level's border are dropped: the patch, its 7 × 7 means and the Harris window fit.
const BORDER: usize = 20;

/// The 16 pixels of the Bresenham circle of radius 3, clockwise from the top.
const CIRCLE: [(i32, i32); 16] = [
    (0, -3),
    (1, -3),
    (2, -2),
    (3, -1),
    (3, 0),
    (3, 1),
    (2, 2),
    (1, 3),
    (0, 3),
    (-1, 3),
    (-2, 2),
    (-3, 1),
    (-3, 0),
    (-3, -1),
    (-2, -2),
    (-1, -3),
];

/// A grey image of one pyramid level.
struct Level {
    width: usize,
    height: usize,
    pixels: Vec<u8>,
    /// Full-image pixels per pixel of this level.
    scale: f32,
}

impl Level {
    #[inline]
    fn at(&self, x: i32, y: i32) -> i32 {
        self.pixels[y as usize * self.width + x as usize] as i32
    }

    /// The next level: this one resampled bilinearly by `factor`.
    fn down(&self, factor: f32) -> Level {
        let (width, height) = (
            (self.width as f32 / factor).round() as usize,
            (self.height as f32 / factor).round() as usize,
        );
        let mut pixels = vec![0u8; width * height];
        pixels.par_chunks_mut(width.max(1)).enumerate().for_each(|(y, row)| {
            let sy = ((y as f32 + 0.5) * factor - 0.5).clamp(0.0, (self.height - 1) as f32);
            let (y0, fy) = (sy as usize, sy.fract());
            let y1 = (y0 + 1).min(self.height - 1);
            for (x, out) in row.iter_mut().enumerate() {
                let sx = ((x as f32 + 0.5) * factor - 0.5).clamp(0.0, (self.width - 1) as f32);
                let (x0, fx) = (sx as usize, sx.fract());
                let x1 = (x0 + 1).min(self.width - 1);
                let g = |x: usize, y: usize| self.pixels[y * self.width + x] as f32;
                let top = g(x0, y0) + fx * (g(x1, y0) - g(x0, y0));
                let bottom = g(x0, y1) + fx * (g(x1, y1) - g(x0, y1));
                // Rounding half up by hand: `f32::round` is a libm call, not an instruction.
                *out = (top + fy * (bottom - top) + 0.5) as u8;
            }
        });
        Level {
            width,
            height,
            pixels,
            scale: self.scale * factor,
        }
    }
}

/// The FAST score of a pixel when 9 contiguous pixels of the circle are all brighter than `p + t` or all darker
/// than `p − t`: the larger of the summed excesses over the threshold of the brighter and of the darker pixels.
#[inline]
fn fast_score(level: &Level, x: i32, y: i32, t: i32) -> Option<i32> {
    let p = level.at(x, y);
    // Any 9-pixel arc contains at least two of the four compass pixels.
    let compass = [0, 4, 8, 12].map(|k| level.at(x + CIRCLE[k].0, y + CIRCLE[k].1));
    let brighter = compass.iter().filter(|&&v| v > p + t).count();
    let darker = compass.iter().filter(|&&v| v < p - t).count();
    if brighter < 2 && darker < 2 {
        return None;
    }
    let (mut up, mut down, mut up_sum, mut down_sum) = (0u32, 0u32, 0, 0);
    for (k, &(dx, dy)) in CIRCLE.iter().enumerate() {
        let v = level.at(x + dx, y + dy);
        if v > p + t {
            up |= 1 << k;
            up_sum += v - p - t;
        } else if v < p - t {
            down |= 1 << k;
            down_sum += p - v - t;
        }
    }
    match (has_arc_of_nine(up), has_arc_of_nine(down)) {
        (false, false) => None,
        _ => Some(up_sum.max(down_sum)),
    }
}

/// Whether the 16-bit circular mask has 9 consecutive set bits.
fn has_arc_of_nine(mask: u32) -> bool {
    let doubled = mask | (mask << 16);
    let mut run = doubled;
    for shift in 1..9 {
        run &= doubled >> shift;
    }
    run != 0
}

/// Harris response (k = 0.04) over the 7 × 7 window of Sobel gradients around a pixel.
fn harris(level: &Level, x: i32, y: i32) -> f32 {
    let (mut xx, mut yy, mut xy) = (0f32, 0f32, 0f32);
    for v in y - 3..=y + 3 {
        for u in x - 3..=x + 3 {
            let g = |du: i32, dv: i32| level.at(u + du, v + dv) as f32;
            let gx = (g(1, -1) + 2.0 * g(1, 0) + g(1, 1)) - (g(-1, -1) + 2.0 * g(-1, 0) + g(-1, 1));
            let gy = (g(-1, 1) + 2.0 * g(0, 1) + g(1, 1)) - (g(-1, -1) + 2.0 * g(0, -1) + g(1, -1));
            xx += gx * gx;
            yy += gy * gy;
            xy += gx * gy;
        }
    }
    // Scaled so that responses of different images are of a readable size.
    let norm = 1.0 / (4.0 * 49.0 * 255.0);
    let (xx, yy, xy) = (xx * norm, yy * norm, xy * norm);
    xx * yy - xy * xy - 0.04 * (xx + yy) * (xx + yy)
}

/// The `quota` best corners of a level: FAST corners, non-maximum suppressed (3 × 3) on the FAST score, the best
/// `2 · quota` of those ranked by the Harris response (ORB's order: the Harris window costs too much for every
/// FAST corner of a textured 12 MP image). Returns (x, y, Harris response), best first.
fn corners(level: &Level, threshold: u8, quota: usize) -> Vec<(i32, i32, f32)> {
    let (w, h) = (level.width, level.height);
    if w <= 2 * BORDER || h <= 2 * BORDER {
        return Vec::new();
    }
    let t = threshold as i32;
    let rows: Vec<Vec<(i32, i32)>> = (BORDER..h - BORDER)
        .into_par_iter()
        .map(|y| {
            (BORDER..w - BORDER)
                .filter_map(|x| fast_score(level, x as i32, y as i32, t).map(|s| (x as i32, s)))
                .collect()
        })
        .collect();
    let score = |x: i32, y: i32| -> i32 {
        let Some(row) = (y as usize).checked_sub(BORDER).and_then(|r| rows.get(r)) else {
            return -1;
        };
        row.binary_search_by_key(&x, |c| c.0).map_or(-1, |i| row[i].1)
    };
    let mut found: Vec<(i32, i32, i32)> = Vec::new();
    for (r, row) in rows.iter().enumerate() {
        let y = (r + BORDER) as i32;
        for &(x, s) in row {
            // Strict against earlier neighbours, not later ones: a plateau keeps exactly one corner.
            let is_max = (-1..=1).all(|dy| {
                (-1..=1).all(|dx| {
                    let n = score(x + dx, y + dy);
                    (dx, dy) == (0, 0) || n < s || (n == s && (dy, dx) > (0, 0))
                })
            });
            if is_max {
                found.push((x, y, s));
            }
        }
    }
    found.sort_by(|a, b| b.2.cmp(&a.2).then((a.1, a.0).cmp(&(b.1, b.0))));
    found.truncate(2 * quota);
    let mut ranked: Vec<(i32, i32, f32)> = found.par_iter().map(|&(x, y, _)| (x, y, harris(level, x, y))).collect();
    ranked.sort_by(|a, b| b.2.total_cmp(&a.2).then((a.1, a.0).cmp(&(b.1, b.0))));
    ranked.truncate(quota);
    ranked
}

/// Orientation by the intensity centroid of the circular patch.
fn orientation(level: &Level, x: i32, y: i32) -> f32 {
    let (mut m10, mut m01) = (0i64, 0i64);
    let r2 = PATCH_RADIUS * PATCH_RADIUS;
    for dy in -PATCH_RADIUS..=PATCH_RADIUS {
        for dx in -PATCH_RADIUS..=PATCH_RADIUS {
            if dx * dx + dy * dy <= r2 {
                let v = level.at(x + dx, y + dy) as i64;
                m10 += dx as i64 * v;
                m01 += dy as i64 * v;
            }
        }
    }
    (m01 as f32).atan2(m10 as f32)
}

/// The 256 comparison pairs: points of an isotropic Gaussian (σ = 31 / 5) inside the patch's circle, from a fixed
/// generator (SplitMix64 and Box–Muller) so that every run and every machine compares the same pixels.
fn pattern() -> [[(f32, f32); 2]; 256] {
    let mut rng = lineflow_photogrammetry::random::Rng::from_state(0x6C69_6E65_666C_6F77);
    let mut next = move || lineflow_photogrammetry::random::unit(rng.next_u64());
    let sigma = 31.0 / 5.0;
    let limit = (PATCH_RADIUS as f64 - 1.0).powi(2);
    let mut point = || loop {
        let (u, v) = (next().max(1e-300), next());
        let r = (-2.0 * u.ln()).sqrt() * sigma;
        let (x, y) = (r * (std::f64::consts::TAU * v).cos(), r * (std::f64::consts::TAU * v).sin());
        if x * x + y * y <= limit {
            return (x as f32, y as f32);
        }
    };
    std::array::from_fn(|_| [point(), point()])
}

/// The steered descriptor of a keypoint: each comparison is between the 7 × 7 means (sums, from the level's
/// integral image) around its two rotated points, which single pixels would make noisy.
fn describe(sums: &Integral, x: i32, y: i32, angle: f32, pattern: &[[(f32, f32); 2]; 256]) -> [u8; 32] {
    let (s, c) = angle.sin_cos();
    let at = |p: (f32, f32)| {
        let u = (x + (p.0 * c - p.1 * s).round() as i32) as usize;
        let v = (y + (p.0 * s + p.1 * c).round() as i32) as usize;
        sums.sum_inside(u - 3, v - 3, u + 4, v + 4)
    };
    let mut out = [0u8; 32];
    for (k, pair) in pattern.iter().enumerate() {
        if at(pair[0]) < at(pair[1]) {
            out[k / 8] |= 1 << (k % 8);
        }
    }
    out
}

/// ORB features of an 8-bit grey image, strongest first.
pub fn orb(pixels: &[u8], width: usize, height: usize, p: &OrbParams) -> Vec<OrbFeature> {
    if width * height == 0 || pixels.len() < width * height {
        return Vec::new();
    }
    let mut levels = vec![Level {
        width,
        height,
        pixels: pixels[..width * height].to_vec(),
        scale: 1.0,
    }];
    while levels.len() < p.levels {
        let next = levels[levels.len() - 1].down(p.scale_factor);
        if next.width <= 2 * BORDER || next.height <= 2 * BORDER {
            break;
        }
        levels.push(next);
    }
    // Each level's share of the keypoints follows its area, as ORB's.
    let areas: Vec<f64> = levels.iter().map(|l| (l.width * l.height) as f64).collect();
    let total: f64 = areas.iter().sum();
    let pattern = pattern();
    let mut features: Vec<OrbFeature> = Vec::new();
    for (level, area) in levels.iter().zip(&areas) {
        let quota = ((p.max_keypoints as f64 * area / total).ceil() as usize).max(1);
        let found = corners(level, p.fast_threshold, quota);
        let sums = Integral::new(&level.pixels, level.width, level.height);
        features.par_extend(found.par_iter().map(|&(x, y, response)| {
            let angle = orientation(level, x, y);
            OrbFeature {
                col: (x as f32 + 0.5) * level.scale - 0.5,
                row: (y as f32 + 0.5) * level.scale - 0.5,
                scale_px: PATCH_RADIUS as f32 * level.scale,
                orientation: angle,
                response,
                descriptor: describe(&sums, x, y, angle, &pattern),
            }
        }));
    }
    features.sort_by(|a, b| {
        b.response
            .total_cmp(&a.response)
            .then(a.row.total_cmp(&b.row))
            .then(a.col.total_cmp(&b.col))
    });
    features.truncate(p.max_keypoints);
    features
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth random texture (deterministic), `w × h`.
    fn texture(w: usize, h: usize, seed: u64) -> Vec<u8> {
        let mut state = seed;
        let mut coarse = vec![0f32; (w / 8 + 2) * (h / 8 + 2)];
        for v in &mut coarse {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            *v = (state >> 56) as f32;
        }
        let cw = w / 8 + 2;
        (0..w * h)
            .map(|k| {
                let (x, y) = ((k % w) as f32 / 8.0, (k / w) as f32 / 8.0);
                let (x0, y0) = (x as usize, y as usize);
                let (fx, fy) = (x.fract(), y.fract());
                let g = |x: usize, y: usize| coarse[y * cw + x];
                let top = g(x0, y0) + fx * (g(x0 + 1, y0) - g(x0, y0));
                let bottom = g(x0, y0 + 1) + fx * (g(x0 + 1, y0 + 1) - g(x0, y0 + 1));
                (top + fy * (bottom - top)) as u8
            })
            .collect()
    }

    #[test]
    fn an_arc_of_nine_is_found_across_the_wrap_and_eight_are_not_enough() {
        assert!(has_arc_of_nine(0b1111_1111_1000_0000));
        // Bits 12–15 and 0–4: nine across the wrap from pixel 15 to pixel 0.
        assert!(has_arc_of_nine(0xF000 | 0x001F));
        assert!(!has_arc_of_nine(0xF000 | 0x000F));
        assert!(!has_arc_of_nine(0b0000_0000_1111_1111));
        assert!(!has_arc_of_nine(0b1010_1010_1010_1010));
    }

    #[test]
    fn a_bright_square_has_fast_corners_at_its_corners_only() {
        let (w, h) = (80, 80);
        let mut img = vec![40u8; w * h];
        for y in 30..50 {
            for x in 30..50 {
                img[y * w + x] = 200;
            }
        }
        let level = Level {
            width: w,
            height: h,
            pixels: img,
            scale: 1.0,
        };
        let found = corners(&level, 20, 10);
        assert_eq!(found.len(), 4, "{found:?}");
        // The Harris maximum of a corner lies within two pixels of it.
        let near = |v: i32| (28..=32).contains(&v) || (47..=51).contains(&v);
        for (x, y, _) in found {
            assert!(near(x) && near(y), "({x}, {y})");
        }
    }

    #[test]
    fn the_same_texture_shifted_and_rotated_gives_the_same_descriptors() {
        let (w, h) = (320, 240);
        let img = texture(w + 16, h + 16, 7);
        let crop = |dx: usize, dy: usize| -> Vec<u8> { (0..h).flat_map(|y| img[(y + dy) * (w + 16) + dx..][..w].to_vec()).collect() };
        let (a, b) = (crop(0, 0), crop(5, 3));
        let p = OrbParams {
            max_keypoints: 300,
            ..Default::default()
        };
        let (fa, fb) = (orb(&a, w, h, &p), orb(&b, w, h, &p));
        assert!(fa.len() > 50, "{} keypoints", fa.len());
        // Every full-resolution keypoint of the shifted image found again 5 px left and 3 px up with an identical
        // descriptor (the coarser levels resample a shifted image differently).
        let full: Vec<&OrbFeature> = fb.iter().filter(|q| q.scale_px == PATCH_RADIUS as f32).collect();
        let same = full
            .iter()
            .filter(|q| {
                fa.iter()
                    .any(|k| (k.col - q.col - 5.0).abs() < 0.01 && (k.row - q.row - 3.0).abs() < 0.01 && k.descriptor == q.descriptor)
            })
            .count();
        assert!(full.len() > 30 && same as f64 > 0.9 * full.len() as f64, "{same} of {}", full.len());
        // A 90° rotation: the descriptors of corresponding keypoints stay close (steering), far below random (128).
        let rotated: Vec<u8> = (0..w)
            .flat_map(|x| (0..h).rev().map(move |y| (x, y)))
            .map(|(x, y)| a[y * w + x])
            .collect();
        let fr = orb(&rotated, h, w, &p);
        let mut distances = Vec::new();
        for k in &fa {
            // (col, row) in `a` is (h − 1 − row, col) in the rotated image.
            let (c, r) = (h as f32 - 1.0 - k.row, k.col);
            if let Some(q) = fr.iter().find(|q| (q.col - c).abs() < 0.6 && (q.row - r).abs() < 0.6) {
                let d: u32 = k.descriptor.iter().zip(&q.descriptor).map(|(x, y)| (x ^ y).count_ones()).sum();
                distances.push(d);
            }
        }
        distances.sort_unstable();
        assert!(distances.len() > 20, "{} found again", distances.len());
        let median = distances[distances.len() / 2];
        assert!(median < 40, "median Hamming distance {median} over {} pairs", distances.len());
    }
}
