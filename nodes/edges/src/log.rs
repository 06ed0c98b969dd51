//! Laplacian of Gaussian: zero crossings of the smoothed Laplacian where the Sobel gradient is strong enough.
use rayon::prelude::*;

use lineflow_imaging::gradient;

fn gaussian_kernel(sigma: f64) -> Vec<f32> {
    let r = (3.0 * sigma).ceil().max(1.0) as isize;
    let k: Vec<f32> = (-r..=r).map(|i| (-((i * i) as f64) / (2.0 * sigma * sigma)).exp() as f32).collect();
    let s: f32 = k.iter().sum();
    k.into_iter().map(|v| v / s).collect()
}

fn blur(src: &[f32], w: usize, h: usize, k: &[f32]) -> Vec<f32> {
    let r = (k.len() / 2) as isize;
    let mut tmp = vec![0f32; w * h];
    tmp.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        for (x, o) in out.iter_mut().enumerate() {
            *o = k
                .iter()
                .enumerate()
                .map(|(j, kv)| kv * src[y * w + (x as isize + j as isize - r).clamp(0, w as isize - 1) as usize])
                .sum();
        }
    });
    let mut dst = vec![0f32; w * h];
    dst.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        for (x, o) in out.iter_mut().enumerate() {
            *o = k
                .iter()
                .enumerate()
                .map(|(j, kv)| kv * tmp[(y as isize + j as isize - r).clamp(0, h as isize - 1) as usize * w + x])
                .sum();
        }
    });
    dst
}

/// LoG edges: Gaussian of `sigma`, 4-neighbour Laplacian, a pixel where the sign changes to its right or lower
/// neighbour and which is the nearer of the two to zero, kept when its Sobel magnitude exceeds `threshold`.
pub fn log(gray: &[u8], w: usize, h: usize, sigma: f64, threshold: f64) -> Vec<u8> {
    let mut map = vec![0u8; w * h];
    if w < 2 || h < 2 {
        return map;
    }
    let g = gradient(gray, w, h);
    let smooth = blur(&gray.iter().map(|&v| v as f32).collect::<Vec<_>>(), w, h, &gaussian_kernel(sigma));
    let at = |x: usize, y: usize| smooth[y * w + x];
    let mut lap = vec![0f32; w * h];
    lap.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        for (x, o) in out.iter_mut().enumerate() {
            let (l, r) = (x.saturating_sub(1), (x + 1).min(w - 1));
            let (u, d) = (y.saturating_sub(1), (y + 1).min(h - 1));
            *o = at(l, y) + at(r, y) + at(x, u) + at(x, d) - 4.0 * at(x, y);
        }
    });
    let t2 = (threshold * threshold) as i32;
    let mut mark = |i: usize, j: usize| {
        let (a, b) = (lap[i], lap[j]);
        if (a < 0.0) != (b < 0.0) && a != b {
            let k = if a.abs() <= b.abs() { i } else { j };
            if g.mag2[k] > t2 {
                map[k] = 2;
            }
        }
    };
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if x + 1 < w {
                mark(i, i + 1);
            }
            if y + 1 < h {
                mark(i, i + w);
            }
        }
    }
    map
}

/// The image smoothed by a Gaussian of `sigma` pixels (rounded back to 8 bits), for detectors that, like
/// MATLAB's Canny, differentiate a smoothed image.
pub fn gaussian_blur(gray: &[u8], w: usize, h: usize, sigma: f64) -> Vec<u8> {
    if w == 0 || h == 0 {
        return Vec::new();
    }
    let src: Vec<f32> = gray.iter().map(|&v| v as f32).collect();
    blur(&src, w, h, &gaussian_kernel(sigma))
        .into_iter()
        .map(|v| v.round().clamp(0.0, 255.0) as u8)
        .collect()
}
