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

/// Sobel gradient and squared magnitude of row `y` into the three output rows (each `width` long).
pub fn gradient_row(gray: &[u8], width: usize, height: usize, y: usize, gx: &mut [i16], gy: &mut [i16], mag2: &mut [i32]) {
    let row = |r: isize| {
        let r = r.clamp(0, height as isize - 1) as usize;
        &gray[r * width..(r + 1) * width]
    };
    let (up, mid, down) = (row(y as isize - 1), row(y as isize), row(y as isize + 1));
    let p = |row: &[u8], c: usize| row[c] as i32;
    let mut edge = |x: usize| {
        let l = x.saturating_sub(1);
        let r = (x + 1).min(width - 1);
        let dx = (p(up, r) + 2 * p(mid, r) + p(down, r)) - (p(up, l) + 2 * p(mid, l) + p(down, l));
        let dy = (p(down, l) + 2 * p(down, x) + p(down, r)) - (p(up, l) + 2 * p(up, x) + p(up, r));
        gx[x] = dx as i16;
        gy[x] = dy as i16;
        mag2[x] = dx * dx + dy * dy;
    };
    edge(0);
    edge(width - 1);
    if width < 3 {
        return;
    }
    // Interior: windows instead of clamped indices, so the loop has no bounds checks and vectorises.
    let interior = up.windows(3).zip(mid.windows(3)).zip(down.windows(3));
    let outs = gx[1..width - 1]
        .iter_mut()
        .zip(gy[1..width - 1].iter_mut())
        .zip(mag2[1..width - 1].iter_mut());
    for (((u, m), d), ((ox, oy), om)) in interior.zip(outs) {
        let (u0, u1, u2) = (u[0] as i32, u[1] as i32, u[2] as i32);
        let (m0, m2) = (m[0] as i32, m[2] as i32);
        let (d0, d1, d2) = (d[0] as i32, d[1] as i32, d[2] as i32);
        let dx = (u2 - u0) + 2 * (m2 - m0) + (d2 - d0);
        let dy = (d0 + 2 * d1 + d2) - (u0 + 2 * u1 + u2);
        *ox = dx as i16;
        *oy = dy as i16;
        *om = dx * dx + dy * dy;
    }
}

/// The gradient at one pixel.
pub fn gradient_at(gray: &[u8], width: usize, height: usize, x: usize, y: usize) -> (i32, i32) {
    let at = |c: isize, r: isize| gray[r.clamp(0, height as isize - 1) as usize * width + c.clamp(0, width as isize - 1) as usize] as i32;
    let (x, y) = (x as isize, y as isize);
    let dx = (at(x + 1, y - 1) + 2 * at(x + 1, y) + at(x + 1, y + 1)) - (at(x - 1, y - 1) + 2 * at(x - 1, y) + at(x - 1, y + 1));
    let dy = (at(x - 1, y + 1) + 2 * at(x, y + 1) + at(x + 1, y + 1)) - (at(x - 1, y - 1) + 2 * at(x, y - 1) + at(x + 1, y - 1));
    (dx, dy)
}

/// Sobel gradient of a `width × height` grey image, whole.
pub fn gradient(gray: &[u8], width: usize, height: usize) -> Gradient {
    let n = width * height;
    let (mut gx, mut gy, mut mag2) = (vec![0i16; n], vec![0i16; n], vec![0i32; n]);
    if n > 0 {
        gx.par_chunks_mut(width)
            .zip(gy.par_chunks_mut(width))
            .zip(mag2.par_chunks_mut(width))
            .enumerate()
            .for_each(|(y, ((gxr, gyr), mr))| gradient_row(gray, width, height, y, gxr, gyr, mr));
    }
    Gradient {
        width,
        height,
        gx,
        gy,
        mag2,
    }
}
