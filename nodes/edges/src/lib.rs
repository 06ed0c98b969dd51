//! Edge detectors on 8-bit grey images, as plain functions. Thresholds apply to the **L2** magnitude of the 3×3
//! Sobel gradient of the 8-bit image (`sqrt(gx² + gy²)`, at most 1442), as `cv2.Canny(..., L2gradient=True)`;
//! comparisons run on the squared integer magnitude, so results match OpenCV's except at exact ties.
//! Every detector thins to one-pixel-wide edges by non-maximum suppression (LoG by its zero crossings).
#![warn(missing_docs)]

mod gradient;
mod log;

pub use gradient::{gradient, Gradient};

use lineflow_messages::EdgePixel;

/// Canny's low threshold as a share of the high one, as the thesis found best.
pub const DEFAULT_LOW_RATIO: f64 = 0.4;

/// An edge pixel list, row-major, with the gradient each was found with.
pub fn pixels(g: &Gradient, keep: &[u8]) -> Vec<EdgePixel> {
    let mut out = Vec::new();
    for (i, &k) in keep.iter().enumerate() {
        if k == EDGE {
            let (gx, gy) = (g.gx[i] as f32, g.gy[i] as f32);
            out.push(EdgePixel {
                col: (i % g.width) as u16,
                row: (i / g.width) as u16,
                magnitude: (g.mag2[i] as f32).sqrt(),
                direction_rad: gy.atan2(gx),
            });
        }
    }
    out
}

const EDGE: u8 = 2;
const CANDIDATE: u8 = 1;

/// Non-maximum suppression along the gradient direction (OpenCV's sector rules); marks survivors above `low2`
/// as candidates and those above `high2` as edges (squared magnitudes).
fn suppress(g: &Gradient, low2: i32, high2: i32) -> Vec<u8> {
    use rayon::prelude::*;
    let (w, h) = (g.width, g.height);
    // tan(22.5°) and tan(67.5°) in 15-bit fixed point, as OpenCV does.
    const TG22: i64 = 13573;
    let mut map = vec![0u8; w * h];
    if w * h == 0 {
        return map;
    }
    map.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let m = |x: isize, y: isize| -> i32 {
            if x < 0 || y < 0 || x >= w as isize || y >= h as isize {
                0
            } else {
                g.mag2[y as usize * w + x as usize]
            }
        };
        for (x, out) in row.iter_mut().enumerate() {
            let i = y * w + x;
            let v = g.mag2[i];
            if v <= low2 {
                continue;
            }
            let (xs, ys) = (g.gx[i] as i64, g.gy[i] as i64);
            let (ax, ay) = (xs.abs(), ys.abs() << 15);
            let tg22x = ax * TG22;
            let (xi, yi) = (x as isize, y as isize);
            let max = if ay < tg22x {
                v > m(xi - 1, yi) && v >= m(xi + 1, yi)
            } else {
                let tg67x = tg22x + (ax << 16);
                if ay > tg67x {
                    v > m(xi, yi - 1) && v >= m(xi, yi + 1)
                } else {
                    let s: isize = if (xs ^ ys) < 0 { -1 } else { 1 };
                    v > m(xi - s, yi - 1) && v > m(xi + s, yi + 1)
                }
            };
            if max {
                *out = if v > high2 { EDGE } else { CANDIDATE };
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
pub fn canny(g: &Gradient, low: f64, high: f64) -> Vec<u8> {
    let mut map = suppress(g, squared(low), squared(high));
    let (w, h) = (g.width as isize, g.height as isize);
    let mut stack: Vec<usize> = map.iter().enumerate().filter(|(_, &k)| k == EDGE).map(|(i, _)| i).collect();
    while let Some(i) = stack.pop() {
        let (x, y) = ((i % g.width) as isize, (i / g.width) as isize);
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
    map
}

/// Sobel: the gradient maxima above `threshold`.
pub fn sobel(g: &Gradient, threshold: f64) -> Vec<u8> {
    let t2 = squared(threshold);
    suppress(g, t2, t2.saturating_sub(1))
}

pub use log::log;
