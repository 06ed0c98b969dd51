//! Small raster plots for the report: histograms and front/top views of segments coloured by error. No text in
//! the pictures; the report's captions give axes and ranges.
use std::path::Path;

use anyhow::{Context, Result};
use image::{Rgb, RgbImage};

use crate::geometry::Seg;

const WHITE: Rgb<u8> = Rgb([255, 255, 255]);
const AXIS: Rgb<u8> = Rgb([60, 60, 60]);
const GREY: Rgb<u8> = Rgb([205, 205, 205]);
const BAR: Rgb<u8> = Rgb([70, 110, 180]);
const UNMATCHED: Rgb<u8> = Rgb([200, 0, 200]);

fn line(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), c: Rgb<u8>) {
    let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as usize).max(1);
    for k in 0..=n {
        let t = k as f64 / n as f64;
        let (x, y) = (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
        if x >= 0.0 && y >= 0.0 && (x as u32) < img.width() && (y as u32) < img.height() {
            img.put_pixel(x as u32, y as u32, c);
        }
    }
}

fn rect(img: &mut RgbImage, x0: u32, y0: u32, x1: u32, y1: u32, c: Rgb<u8>) {
    for y in y0..y1.min(img.height()) {
        for x in x0..x1.min(img.width()) {
            img.put_pixel(x, y, c);
        }
    }
}

/// Green (0) through yellow to red (1 and above).
pub fn ramp(t: f64) -> Rgb<u8> {
    let t = t.clamp(0.0, 1.0);
    let (r, g) = if t < 0.5 { (2.0 * t, 1.0) } else { (1.0, 2.0 * (1.0 - t)) };
    Rgb([(r * 220.0) as u8, (g * 190.0) as u8, 40])
}

fn save(img: &RgbImage, path: &Path) -> Result<()> {
    img.save(path).with_context(|| format!("cannot write {}", path.display()))
}

/// Histogram of `values` over [0, max) in `bins` bars, the last bar collecting everything beyond.
pub fn histogram(values: &[f64], max: f64, bins: usize, path: &Path) -> Result<()> {
    let (w, h, m) = (640u32, 300u32, 20u32);
    let mut img = RgbImage::from_pixel(w, h, WHITE);
    let mut counts = vec![0usize; bins];
    for v in values.iter().filter(|v| v.is_finite()) {
        counts[((v / max * bins as f64) as usize).min(bins - 1)] += 1;
    }
    let top = counts.iter().copied().max().unwrap_or(1).max(1);
    let bw = (w - 2 * m) / bins as u32;
    for (i, c) in counts.iter().enumerate() {
        let bh = ((h - 2 * m) as f64 * *c as f64 / top as f64) as u32;
        let x0 = m + i as u32 * bw;
        rect(&mut img, x0 + 1, h - m - bh, x0 + bw - 1, h - m, BAR);
    }
    line(&mut img, (m as f64, (h - m) as f64), ((w - m) as f64, (h - m) as f64), AXIS);
    line(&mut img, (m as f64, m as f64), (m as f64, (h - m) as f64), AXIS);
    save(&img, path)
}

/// Segments projected on two object axes (0 = X, 1 = Y, 2 = Z; the second axis points up in the picture), truth
/// in grey beneath, estimates coloured by `error / max_error` (magenta: unmatched), with a colour bar below.
pub fn view(truth: &[Seg], est: &[Seg], error: &[f64], max_error: f64, axes: (usize, usize), path: &Path) -> Result<()> {
    let (w, h, m) = (1000u32, 640u32, 20u32);
    let bar = 24u32;
    let mut img = RgbImage::from_pixel(w, h, WHITE);
    let pts = truth.iter().chain(est).flat_map(|s| [s.a, s.b]);
    let (mut lo, mut hi) = ((f64::INFINITY, f64::INFINITY), (f64::NEG_INFINITY, f64::NEG_INFINITY));
    for p in pts {
        lo = (lo.0.min(p[axes.0]), lo.1.min(p[axes.1]));
        hi = (hi.0.max(p[axes.0]), hi.1.max(p[axes.1]));
    }
    let span = ((hi.0 - lo.0) / (w - 2 * m) as f64)
        .max((hi.1 - lo.1) / (h - 3 * m - bar) as f64)
        .max(1e-9);
    let to = |p: &lineflow_photogrammetry::Vec3| {
        (
            m as f64 + (p[axes.0] - lo.0) / span,
            (h - 2 * m - bar) as f64 - (p[axes.1] - lo.1) / span,
        )
    };
    for s in truth {
        line(&mut img, to(&s.a), to(&s.b), GREY);
    }
    for (s, e) in est.iter().zip(error) {
        let c = if e.is_finite() { ramp(e / max_error) } else { UNMATCHED };
        line(&mut img, to(&s.a), to(&s.b), c);
    }
    for x in m..w - m {
        let c = ramp((x - m) as f64 / (w - 2 * m) as f64);
        rect(&mut img, x, h - m - bar, x + 1, h - m, c);
    }
    save(&img, path)
}

/// Polylines (pixel coordinates, `(col, row)`) over a photograph dimmed to half its contrast, each coloured by
/// `error / max_error` (magenta: unmatched), two pixels wide.
pub fn over_image(mut img: RgbImage, polylines: &[(Vec<(f64, f64)>, f64)], max_error: f64, path: &Path) -> Result<()> {
    for p in img.pixels_mut() {
        for c in p.0.iter_mut() {
            *c = 64 + *c / 2;
        }
    }
    for (points, e) in polylines {
        let c = if e.is_finite() { ramp(e / max_error) } else { UNMATCHED };
        for w in points.windows(2) {
            for d in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)] {
                line(&mut img, (w[0].0 + d.0, w[0].1 + d.1), (w[1].0 + d.0, w[1].1 + d.1), c);
            }
        }
    }
    save(&img, path)
}
