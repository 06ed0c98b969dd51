//! The 3×3 Sobel gradient of an 8-bit image with replicated borders (OpenCV's `BORDER_REPLICATE`).
use rayon::prelude::*;

/// Gradient components and squared L2 magnitude, row-major.
#[derive(Debug, Clone)]
pub struct Gradient {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// ∂I/∂x (columns to the right).
    pub gx: Vec<i16>,
    /// ∂I/∂y (rows down).
    pub gy: Vec<i16>,
    /// gx² + gy².
    pub mag2: Vec<i32>,
}

/// Sobel gradient of a `width × height` grey image.
pub fn gradient(gray: &[u8], width: usize, height: usize) -> Gradient {
    let n = width * height;
    let (mut gx, mut gy, mut mag2) = (vec![0i16; n], vec![0i16; n], vec![0i32; n]);
    if n == 0 {
        return Gradient {
            width,
            height,
            gx,
            gy,
            mag2,
        };
    }
    gx.par_chunks_mut(width)
        .zip(gy.par_chunks_mut(width))
        .zip(mag2.par_chunks_mut(width))
        .enumerate()
        .for_each(|(y, ((gxr, gyr), mr))| {
            let row = |r: isize| {
                let r = r.clamp(0, height as isize - 1) as usize;
                &gray[r * width..(r + 1) * width]
            };
            let (up, mid, down) = (row(y as isize - 1), row(y as isize), row(y as isize + 1));
            for x in 0..width {
                let l = x.saturating_sub(1);
                let r = (x + 1).min(width - 1);
                let p = |row: &[u8], c: usize| row[c] as i32;
                let dx = (p(up, r) + 2 * p(mid, r) + p(down, r)) - (p(up, l) + 2 * p(mid, l) + p(down, l));
                let dy = (p(down, l) + 2 * p(down, x) + p(down, r)) - (p(up, l) + 2 * p(up, x) + p(up, r));
                gxr[x] = dx as i16;
                gyr[x] = dy as i16;
                mr[x] = dx * dx + dy * dy;
            }
        });
    Gradient {
        width,
        height,
        gx,
        gy,
        mag2,
    }
}
