//! Sub-pixel positions of edge pixels, for the stages that fit lines to an edge detector's pixels.
use lineflow_messages::EdgePixel;
use rayon::prelude::*;

use crate::gradient::Planes;

/// Sub-pixel positions of edge pixels: the peak of a parabola through the gradient magnitude at the pixel and
/// its two neighbours across the edge (the nearest of the 8 directions to the gradient), as (col, row).
/// Non-maximum suppression puts an edge between two pixels on one of them; this removes that half-pixel bias.
pub fn subpixel_positions(gray: &[u8], width: usize, height: usize, pixels: &[EdgePixel]) -> Vec<[f64; 2]> {
    subpixel_positions_in(&Planes::gray(gray), width, height, pixels)
}

/// [`subpixel_positions`] on the gradient of the strongest plane, as the edge detector found the pixels.
pub fn subpixel_positions_in(planes: &Planes, width: usize, height: usize, pixels: &[EdgePixel]) -> Vec<[f64; 2]> {
    let mag = |x: isize, y: isize| {
        let (x, y) = (x.clamp(0, width as isize - 1) as usize, y.clamp(0, height as isize - 1) as usize);
        let (gx, gy) = planes.gradient_at(width, height, x, y);
        ((gx * gx + gy * gy) as f64).sqrt()
    };
    pixels
        .par_iter()
        .map(|p| {
            let (x, y) = (p.col as isize, p.row as isize);
            let (s, c) = (p.direction_rad as f64).sin_cos();
            // The 8-neighbour step nearest to the gradient direction.
            let (dx, dy) = (c.round() as isize, s.round() as isize);
            let (dx, dy) = if dx == 0 && dy == 0 { (1, 0) } else { (dx, dy) };
            let (m0, mp, mm) = (mag(x, y), mag(x + dx, y + dy), mag(x - dx, y - dy));
            let denom = mm - 2.0 * m0 + mp;
            let t = if denom < 0.0 {
                (0.5 * (mm - mp) / denom).clamp(-0.5, 0.5)
            } else {
                0.0
            };
            [p.col as f64 + t * dx as f64, p.row as f64 + t * dy as f64]
        })
        .collect()
}
