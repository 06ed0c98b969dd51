//! Edge detectors on 8-bit grey images, as plain functions. Thresholds apply to the **L2** magnitude of the 3×3
//! Sobel gradient of the 8-bit image (`sqrt(gx² + gy²)`, at most 1442), as `cv2.Canny(..., L2gradient=True)`;
//! comparisons run on the squared integer magnitude, so results match OpenCV's except at exact ties.
//! Every detector thins to one-pixel-wide edges by non-maximum suppression (LoG by its zero crossings).
#![warn(missing_docs)]

pub mod detector;
mod log;

use lineflow_imaging::{GradientRow, Planes, RowScratch};

use lineflow_messages::EdgePixel;
use rayon::prelude::*;

pub use detector::{Detector, EdgeParams, EdgeParamsError};

/// Canny's low threshold as a share of the high one, as the thesis found best.
pub const DEFAULT_LOW_RATIO: f64 = 0.4;

/// Canny's default high threshold. Lower finds more of the façade's faint edges (a brick course against the
/// shaded reveal beside it steps by 10 to 20 grey levels): at 50 the 2-D stage's recall on the full-size D2X strip
/// rises from 81.1 % to 84.9 %, but those edges match badly in 3-D (vertical 3-D lines on the true surfaces at
/// 2 GSD: 78 % instead of 93 %), and the 3-D stage's work grows.
pub const DEFAULT_HIGH: f64 = 100.0;

/// The marked pixels of `map` as a row-major list, with the gradient at each (recomputed: cheaper than keeping
/// full-size gradient images for the few per cent of pixels that are edges).
pub fn pixels(gray: &[u8], width: usize, height: usize, map: &[u8]) -> Vec<EdgePixel> {
    pixels_in(&Planes::gray(gray), width, height, map)
}

/// [`pixels`] with the gradient of the strongest plane.
pub fn pixels_in(planes: &Planes, width: usize, height: usize, map: &[u8]) -> Vec<EdgePixel> {
    if width == 0 {
        return Vec::new();
    }
    // Bands of rows in parallel, concatenated in order: the same list as one row-major scan.
    let bands: Vec<Vec<EdgePixel>> = map
        .par_chunks(width * BAND)
        .enumerate()
        .map(|(band, rows)| {
            let mut out = Vec::new();
            for (i, &k) in rows.iter().enumerate() {
                if k == EDGE {
                    let (x, y) = (i % width, band * BAND + i / width);
                    let (gx, gy) = planes.gradient_at(width, height, x, y);
                    out.push(EdgePixel {
                        col: x as u16,
                        row: y as u16,
                        magnitude: ((gx * gx + gy * gy) as f32).sqrt(),
                        direction_rad: (gy as f32).atan2(gx as f32),
                    });
                }
            }
            out
        })
        .collect();
    bands.concat()
}

const EDGE: u8 = 2;
const CANDIDATE: u8 = 1;
/// Rows per parallel band of the fused pass.
const BAND: usize = 64;

/// Gradient and non-maximum suppression in one pass over bands of rows, each band keeping only three gradient
/// rows (as OpenCV does): survivors above `low2` become candidates, above `high2` edges (squared magnitudes).
fn suppress(planes: &Planes, w: usize, h: usize, low2: i32, high2: i32) -> Vec<u8> {
    // tan(22.5°) in 15-bit fixed point, as OpenCV does.
    const TG22: i64 = 13573;
    let mut map = vec![0u8; w * h];
    if w * h == 0 {
        return map;
    }
    map.par_chunks_mut(w * BAND).enumerate().for_each(|(band, rows)| {
        let y0 = band * BAND;
        let (mut gx, mut gy, mut mag) = (vec![vec![0i16; w]; 3], vec![vec![0i16; w]; 3], vec![vec![0i32; w]; 3]);
        let zeros = vec![0i32; w];
        let mut scratch = RowScratch::default();
        let mut fill = |y: usize, gx: &mut [Vec<i16>], gy: &mut [Vec<i16>], mag: &mut [Vec<i32>]| {
            let s = y % 3;
            let out = GradientRow {
                gx: &mut gx[s],
                gy: &mut gy[s],
                mag2: &mut mag[s],
            };
            planes.gradient_row(w, h, y, out, &mut scratch);
        };
        if y0 > 0 {
            fill(y0 - 1, &mut gx, &mut gy, &mut mag);
        }
        fill(y0, &mut gx, &mut gy, &mut mag);
        for (dy, row) in rows.chunks_mut(w).enumerate() {
            let y = y0 + dy;
            if y + 1 < h {
                fill(y + 1, &mut gx, &mut gy, &mut mag);
            }
            let prev: &[i32] = if y > 0 { &mag[(y - 1) % 3] } else { &zeros };
            let next: &[i32] = if y + 1 < h { &mag[(y + 1) % 3] } else { &zeros };
            let (cur, gxr, gyr) = (&mag[y % 3], &gx[y % 3], &gy[y % 3]);
            let at = |r: &[i32], x: isize| if x < 0 || x >= w as isize { 0 } else { r[x as usize] };
            for (x, out) in row.iter_mut().enumerate() {
                let v = cur[x];
                if v <= low2 {
                    continue;
                }
                let (xs, ys) = (gxr[x] as i64, gyr[x] as i64);
                let (ax, ay) = (xs.abs(), ys.abs() << 15);
                let tg22x = ax * TG22;
                let xi = x as isize;
                let max = if ay < tg22x {
                    v > at(cur, xi - 1) && v >= at(cur, xi + 1)
                } else if ay > tg22x + (ax << 16) {
                    v > prev[x] && v >= next[x]
                } else {
                    let s: isize = if (xs ^ ys) < 0 { -1 } else { 1 };
                    v > at(prev, xi - s) && v > at(next, xi + s)
                };
                if max {
                    *out = if v > high2 { EDGE } else { CANDIDATE };
                }
            }
        }
    });
    map
}

fn squared(t: f64) -> i32 {
    let t = t.max(0.0);
    (t * t).min(i32::MAX as f64) as i32
}

/// Canny: suppression, then hysteresis from pixels above `high` through 8-connected pixels above `low`.
pub fn canny(gray: &[u8], width: usize, height: usize, low: f64, high: f64) -> Vec<u8> {
    canny_in(&Planes::gray(gray), width, height, low, high)
}

/// [`canny`] on the gradient of the strongest plane.
pub fn canny_in(planes: &Planes, width: usize, height: usize, low: f64, high: f64) -> Vec<u8> {
    let mut map = suppress(planes, width, height, squared(low), squared(high));
    let (w, h) = (width as isize, height as isize);
    let mut stack: Vec<usize> = Vec::new();
    for i in 0..map.len() {
        if map[i] != EDGE {
            continue;
        }
        stack.push(i);
        while let Some(i) = stack.pop() {
            let (x, y) = ((i % width) as isize, (i / width) as isize);
            for (dx, dy) in [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)] {
                let (nx, ny) = (x + dx, y + dy);
                if nx >= 0 && ny >= 0 && nx < w && ny < h {
                    let j = (ny * w + nx) as usize;
                    if map[j] == CANDIDATE {
                        map[j] = EDGE;
                        stack.push(j);
                    }
                }
            }
        }
    }
    map
}

/// Sobel: the gradient maxima above `threshold`.
pub fn sobel(gray: &[u8], width: usize, height: usize, threshold: f64) -> Vec<u8> {
    sobel_in(&Planes::gray(gray), width, height, threshold)
}

/// [`sobel`] on the gradient of the strongest plane.
pub fn sobel_in(planes: &Planes, width: usize, height: usize, threshold: f64) -> Vec<u8> {
    let t2 = squared(threshold);
    // No hysteresis: with the edge level just below the candidate level every survivor is an edge.
    suppress(planes, width, height, t2, t2.saturating_sub(1))
}

pub use log::{gaussian_blur, log};
