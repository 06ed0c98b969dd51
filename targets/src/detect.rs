//! Circular targets in one grey image: a white disc inside a black ring twice its radius, seen as an ellipse from
//! any side.
//!
//! The rings are found first, as connected regions of pixels much darker than their neighbourhood that enclose one
//! bright hole: texture rarely makes a dark annulus around a bright, concentric disc of half its size, which is what
//! the shape tests ask. The centre is then the centroid of the disc's light above the ring's level, inside an
//! ellipse halfway between the disc's edge and the ring's: the blur spreads the disc's light symmetrically into the
//! ring, so no threshold decides where the disc ends, and at a few pixels across the centre lies within a few
//! hundredths of a pixel of the true one (`lineflow bench targets`).
//!
//! Pixel coordinates follow the conventions: integer values at pixel centres.

/// A target found in an image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// The centre of the disc, pixels.
    pub centre: [f64; 2],
    /// The disc's radius, pixels (of a circle of its area; the ring's outer radius is twice that).
    pub radius_px: f64,
    /// The disc's grey level above the ring's.
    pub contrast: f64,
}

/// What counts as a target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectSettings {
    /// Side of the square over which a pixel's neighbourhood is averaged, pixels. It should be well over the
    /// largest ring's diameter, so that a ring's pixels are compared with the wall around it.
    pub window_px: usize,
    /// A ring's pixels are darker than this share of their neighbourhood's mean.
    pub dark_share: f64,
    /// Smallest disc radius, pixels. Below 1.2 px (a disc of 2.4 px, a target of 5) the disc is a blur.
    pub min_radius_px: f64,
    /// Largest disc radius, pixels.
    pub max_radius_px: f64,
    /// Least grey level of the disc above the ring (0–255).
    pub min_contrast: f64,
    /// Least ratio of the ellipse's short axis to its long one: 0.3 takes targets seen up to about 70° off
    /// their normal.
    pub min_axis_ratio: f64,
}

impl Default for DetectSettings {
    fn default() -> Self {
        DetectSettings {
            window_px: 61,
            dark_share: 0.5,
            min_radius_px: 1.2,
            max_radius_px: 60.0,
            min_contrast: 40.0,
            min_axis_ratio: 0.3,
        }
    }
}

/// The targets in an 8-bit grey image (`width × height`, rows packed), in the order of their rings' first pixel
/// (top to bottom, left to right). An image of the wrong size has none.
pub fn detect(gray: &[u8], width: usize, height: usize, settings: &DetectSettings) -> Vec<Detection> {
    if width < 3 || height < 3 || gray.len() != width * height {
        return Vec::new();
    }
    let image = Gray {
        pixels: gray,
        width,
        height,
    };
    let dark = dark_mask(&image, settings);
    let max_side = (4.0 * settings.max_radius_px).ceil() as usize + 2;
    let mut visited = vec![false; dark.len()];
    let mut stack = Vec::new();
    let mut ring = Vec::new();
    let mut found = Vec::new();
    for start in 0..dark.len() {
        if !dark[start] || visited[start] {
            continue;
        }
        // The whole region is visited (so that it is not started again), but only a small one is kept.
        ring.clear();
        let mut bounds = Bounds::at(start % width, start / width);
        visited[start] = true;
        stack.push(start);
        while let Some(i) = stack.pop() {
            let (x, y) = (i % width, i / width);
            bounds.grow(x, y);
            if ring.len() <= max_side * max_side {
                ring.push((x, y));
            }
            for (nx, ny) in neighbours8(x, y, width, height) {
                let j = ny * width + nx;
                if dark[j] && !visited[j] {
                    visited[j] = true;
                    stack.push(j);
                }
            }
        }
        let touches_border = bounds.x0 == 0 || bounds.y0 == 0 || bounds.x1 + 1 == width || bounds.y1 + 1 == height;
        if touches_border || bounds.width() > max_side || bounds.height() > max_side || bounds.width() < 4 || bounds.height() < 4 {
            continue;
        }
        if let Some(d) = examine(&image, &ring, bounds, settings) {
            found.push(d);
        }
    }
    found
}

/// A borrowed grey image.
struct Gray<'a> {
    pixels: &'a [u8],
    width: usize,
    height: usize,
}

impl Gray<'_> {
    fn at(&self, x: usize, y: usize) -> f64 {
        f64::from(self.pixels[y * self.width + x])
    }
}

/// The pixels darker than `dark_share` of the mean of their window, and darker than it by half the least
/// contrast (a uniformly black area is no ring: its pixels are as dark as their neighbourhood). The window's sums
/// run down the columns and along each row, so memory stays one row of sums whatever the image's size.
fn dark_mask(image: &Gray, s: &DetectSettings) -> Vec<bool> {
    let (w, h) = (image.width, image.height);
    let half = s.window_px / 2;
    let row = |y: usize| &image.pixels[y * w..(y + 1) * w];
    // Column sums over the window's rows: at most 255 · window_px, well inside u32.
    let mut columns = vec![0u32; w];
    for y in 0..half.min(h) {
        for (c, &v) in columns.iter_mut().zip(row(y)) {
            *c += u32::from(v);
        }
    }
    let mut dark = vec![false; w * h];
    for y in 0..h {
        if y + half < h {
            for (c, &v) in columns.iter_mut().zip(row(y + half)) {
                *c += u32::from(v);
            }
        }
        if y > half {
            for (c, &v) in columns.iter_mut().zip(row(y - half - 1)) {
                *c -= u32::from(v);
            }
        }
        let rows = ((y + half + 1).min(h) - y.saturating_sub(half)) as f64;
        let mut sum: u64 = columns[..half.min(w)].iter().map(|&c| u64::from(c)).sum();
        for x in 0..w {
            if x + half < w {
                sum += u64::from(columns[x + half]);
            }
            if x > half {
                sum -= u64::from(columns[x - half - 1]);
            }
            let cols = ((x + half + 1).min(w) - x.saturating_sub(half)) as f64;
            let mean = sum as f64 / (rows * cols);
            let v = f64::from(image.pixels[y * w + x]);
            dark[y * w + x] = v < s.dark_share * mean && v + 0.5 * s.min_contrast < mean;
        }
    }
    dark
}

fn neighbours8(x: usize, y: usize, w: usize, h: usize) -> impl Iterator<Item = (usize, usize)> {
    let (x, y) = (x as i64, y as i64);
    (-1..=1)
        .flat_map(move |dy| (-1..=1).map(move |dx| (x + dx, y + dy)))
        .filter(move |&(nx, ny)| (nx, ny) != (x, y) && nx >= 0 && ny >= 0 && nx < w as i64 && ny < h as i64)
        .map(|(nx, ny)| (nx as usize, ny as usize))
}

/// Inclusive pixel bounds.
#[derive(Debug, Clone, Copy)]
struct Bounds {
    x0: usize,
    x1: usize,
    y0: usize,
    y1: usize,
}

impl Bounds {
    fn at(x: usize, y: usize) -> Bounds {
        Bounds {
            x0: x,
            x1: x,
            y0: y,
            y1: y,
        }
    }
    fn grow(&mut self, x: usize, y: usize) {
        self.x0 = self.x0.min(x);
        self.x1 = self.x1.max(x);
        self.y0 = self.y0.min(y);
        self.y1 = self.y1.max(y);
    }
    fn width(&self) -> usize {
        self.x1 - self.x0 + 1
    }
    fn height(&self) -> usize {
        self.y1 - self.y0 + 1
    }
}

/// The area, centroid and second central moments of a set of pixels.
#[derive(Debug, Clone, Copy, Default)]
struct Moments {
    n: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
}

impl Moments {
    fn add(&mut self, x: f64, y: f64) {
        self.n += 1.0;
        self.sx += x;
        self.sy += y;
        self.sxx += x * x;
        self.sxy += x * y;
        self.syy += y * y;
    }
    fn merged(mut self, o: &Moments) -> Moments {
        self.n += o.n;
        self.sx += o.sx;
        self.sy += o.sy;
        self.sxx += o.sxx;
        self.sxy += o.sxy;
        self.syy += o.syy;
        self
    }
    fn centroid(&self) -> [f64; 2] {
        [self.sx / self.n, self.sy / self.n]
    }
    /// Covariance [xx, xy, yy], with each pixel a unit square (1/12 added), so that a small blob's ellipse keeps
    /// its area.
    fn covariance(&self) -> [f64; 3] {
        let [cx, cy] = self.centroid();
        [
            self.sxx / self.n - cx * cx + 1.0 / 12.0,
            self.sxy / self.n - cx * cy,
            self.syy / self.n - cy * cy + 1.0 / 12.0,
        ]
    }
}

/// The eigenvalues (larger first) of a symmetric 2×2 matrix [a, b, c] = [[a, b], [b, c]].
fn eigenvalues([a, b, c]: [f64; 3]) -> (f64, f64) {
    let mean = 0.5 * (a + c);
    let spread = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    (mean + spread, mean - spread)
}

/// Whether the dark region `ring` (inside `bounds`) is a target's ring around its disc, and if so where the disc's
/// centre is.
fn examine(image: &Gray, ring: &[(usize, usize)], bounds: Bounds, s: &DetectSettings) -> Option<Detection> {
    // A local grid with a margin of one cell: 1 ring, 0 not yet reached, 2 outside (reached from the margin).
    let (gw, gh) = (bounds.width() + 2, bounds.height() + 2);
    let mut grid = vec![0u8; gw * gh];
    for &(x, y) in ring {
        grid[(y - bounds.y0 + 1) * gw + (x - bounds.x0 + 1)] = 1;
    }
    // The outside, 4-connected (the ring is 8-connected, so a ring one pixel thick still closes its hole).
    let mut stack = vec![0usize];
    grid[0] = 2;
    while let Some(i) = stack.pop() {
        let (x, y) = (i % gw, i / gw);
        let mut visit = |j: usize| {
            if grid[j] == 0 {
                grid[j] = 2;
                stack.push(j);
            }
        };
        if x > 0 {
            visit(i - 1);
        }
        if x + 1 < gw {
            visit(i + 1);
        }
        if y > 0 {
            visit(i - gw);
        }
        if y + 1 < gh {
            visit(i + gw);
        }
    }
    // The holes: what the outside did not reach.
    let mut holes: Vec<Moments> = Vec::new();
    let mut hole_pixels: Vec<Vec<(usize, usize)>> = Vec::new();
    for start in 0..grid.len() {
        if grid[start] != 0 {
            continue;
        }
        let mut m = Moments::default();
        let mut pixels = Vec::new();
        grid[start] = 3;
        let mut stack = vec![start];
        while let Some(i) = stack.pop() {
            let (gx, gy) = (i % gw, i / gw);
            let (x, y) = (gx + bounds.x0 - 1, gy + bounds.y0 - 1);
            m.add(x as f64, y as f64);
            pixels.push((x, y));
            for j in [i - 1, i + 1, i - gw, i + gw] {
                if grid[j] == 0 {
                    grid[j] = 3;
                    stack.push(j);
                }
            }
        }
        holes.push(m);
        hole_pixels.push(pixels);
    }
    let largest = (0..holes.len()).max_by(|&a, &b| holes[a].n.total_cmp(&holes[b].n))?;
    let all_holes: f64 = holes.iter().map(|m| m.n).sum();
    let disc = holes[largest];
    if disc.n < 0.8 * all_holes {
        return None;
    }
    let mut ring_moments = Moments::default();
    for &(x, y) in ring {
        ring_moments.add(x as f64, y as f64);
    }
    let filled = holes.iter().fold(ring_moments, |acc, h| acc.merged(h));

    // The shape: a disc of half the ring's radius, concentric, both elliptic alike.
    let r_disc = (disc.n / std::f64::consts::PI).sqrt();
    let r_filled = (filled.n / std::f64::consts::PI).sqrt();
    if r_disc < s.min_radius_px || r_disc > s.max_radius_px || !(1.4..=3.2).contains(&(r_filled / r_disc)) {
        return None;
    }
    let (cd, cf) = (disc.centroid(), filled.centroid());
    if (cd[0] - cf[0]).hypot(cd[1] - cf[1]) > 0.2 * r_filled + 0.5 {
        return None;
    }
    let cov = filled.covariance();
    let (major, minor) = eigenvalues(cov);
    if minor <= 0.0 || (minor / major).sqrt() < s.min_axis_ratio || !round(ring, &grid, gw, bounds, cf, cov) {
        return None;
    }
    // A uniform ellipse of semi-axes a, b has variances a²/4 and b²/4: its area is 4π·√(λ₁λ₂).
    let ellipse_area = 4.0 * std::f64::consts::PI * (major * minor).sqrt();
    if !(0.75..=1.25).contains(&(filled.n / ellipse_area)) {
        return None;
    }

    // The levels: the ring's median, the disc's brighter half.
    let mut ring_levels: Vec<f64> = ring.iter().map(|&(x, y)| image.at(x, y)).collect();
    ring_levels.sort_by(f64::total_cmp);
    let ring_level = ring_levels[ring_levels.len() / 2];
    let mut disc_levels: Vec<f64> = hole_pixels[largest].iter().map(|&(x, y)| image.at(x, y)).collect();
    disc_levels.sort_by(f64::total_cmp);
    let bright = &disc_levels[disc_levels.len() / 2..];
    let disc_level = bright.iter().sum::<f64>() / bright.len() as f64;
    let contrast = disc_level - ring_level;
    if contrast < s.min_contrast {
        return None;
    }

    let centre = light_centroid(image, cd, cov, 1.0 + r_disc / r_filled, ring_level)?;
    Some(Detection {
        centre,
        radius_px: r_disc,
        contrast,
    })
}

/// Whether the ring's outline is an ellipse: the outline pixels' distances from the centre, in the units of the
/// ring's own covariance, scatter about their mean by at most 0.35 px plus 3 % of the radius. A square frame
/// around a bright pane (a window) has the moments of an ellipse, but its corners lie 40 % further out than the
/// middles of its sides.
fn round(ring: &[(usize, usize)], grid: &[u8], gw: usize, bounds: Bounds, centre: [f64; 2], cov: [f64; 3]) -> bool {
    let det = cov[0] * cov[2] - cov[1] * cov[1];
    let inv = [cov[2] / det, -cov[1] / det, cov[0] / det];
    let scale = det.sqrt().sqrt();
    let outside = |x: usize, y: usize| {
        let i = (y - bounds.y0 + 1) * gw + (x - bounds.x0 + 1);
        [i - 1, i + 1, i - gw, i + gw].iter().any(|&j| grid[j] == 2)
    };
    let radii: Vec<f64> = ring
        .iter()
        .filter(|&&(x, y)| outside(x, y))
        .map(|&(x, y)| {
            let (dx, dy) = (x as f64 - centre[0], y as f64 - centre[1]);
            (inv[0] * dx * dx + 2.0 * inv[1] * dx * dy + inv[2] * dy * dy).sqrt() * scale
        })
        .collect();
    if radii.len() < 8 {
        return false;
    }
    let mean = radii.iter().sum::<f64>() / radii.len() as f64;
    let rms = (radii.iter().map(|r| (r - mean) * (r - mean)).sum::<f64>() / radii.len() as f64).sqrt();
    rms <= 0.35 + 0.03 * mean
}

/// The centroid of the light above `floor` inside the ellipse of covariance `cov` at Mahalanobis distance `reach`
/// (the filled ring's outline lies at 2, its disc's at twice the radii's ratio), re-centred on its own result three
/// times. The ring's pixels weigh by their noise alone, which averages out; clamping it at zero would bias the
/// centre towards the ring's brighter side.
fn light_centroid(image: &Gray, start: [f64; 2], cov: [f64; 3], reach: f64, floor: f64) -> Option<[f64; 2]> {
    let det = cov[0] * cov[2] - cov[1] * cov[1];
    let inv = [cov[2] / det, -cov[1] / det, cov[0] / det];
    let extent = [(cov[0] * reach * reach).sqrt(), (cov[2] * reach * reach).sqrt()];
    let mut c = start;
    for _ in 0..3 {
        let (x0, x1) = (
            (c[0] - extent[0]).floor().max(0.0) as usize,
            ((c[0] + extent[0]).ceil() as usize).min(image.width - 1),
        );
        let (y0, y1) = (
            (c[1] - extent[1]).floor().max(0.0) as usize,
            ((c[1] + extent[1]).ceil() as usize).min(image.height - 1),
        );
        let (mut sw, mut sx, mut sy) = (0.0, 0.0, 0.0);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (dx, dy) = (x as f64 - c[0], y as f64 - c[1]);
                if inv[0] * dx * dx + 2.0 * inv[1] * dx * dy + inv[2] * dy * dy > reach * reach {
                    continue;
                }
                let w = image.at(x, y) - floor;
                sw += w;
                sx += w * x as f64;
                sy += w * y as f64;
            }
        }
        if sw <= 0.0 {
            return None;
        }
        c = [sx / sw, sy / sw];
    }
    Some(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A target of disc radius `r` (px) centred at `centre`, drawn by supersampling each pixel 8×8 on a wall of
    /// grey `wall`, the disc 240 and the ring 10, squeezed across by `squeeze` (an oblique view).
    fn draw(w: usize, h: usize, targets: &[([f64; 2], f64)], wall: u8, squeeze: f64) -> Vec<u8> {
        draw_with(w, h, targets, wall, squeeze, 240.0)
    }

    fn draw_with(w: usize, h: usize, targets: &[([f64; 2], f64)], wall: u8, squeeze: f64, disc: f64) -> Vec<u8> {
        let mut img = vec![wall; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0.0;
                for sy in 0..8 {
                    for sx in 0..8 {
                        let (px, py) = (x as f64 - 0.5 + (sx as f64 + 0.5) / 8.0, y as f64 - 0.5 + (sy as f64 + 0.5) / 8.0);
                        let mut v = f64::from(wall);
                        for &(c, r) in targets {
                            let d = ((px - c[0]) / squeeze).hypot(py - c[1]);
                            if d <= r {
                                v = disc;
                            } else if d <= 2.0 * r {
                                v = 10.0;
                            }
                        }
                        acc += v;
                    }
                }
                img[y * w + x] = (acc / 64.0).round() as u8;
            }
        }
        img
    }

    #[test]
    fn the_dark_mask_compares_each_pixel_with_the_mean_of_its_window_clipped_at_the_borders() {
        let (w, h) = (23, 17);
        let pixels: Vec<u8> = (0..(w * h) as u64)
            .map(|i| (lineflow_photogrammetry::random::hash(&[i, 7]) % 256) as u8)
            .collect();
        let s = DetectSettings {
            window_px: 7,
            min_contrast: 10.0,
            ..DetectSettings::default()
        };
        let mask = dark_mask(
            &Gray {
                pixels: &pixels,
                width: w,
                height: h,
            },
            &s,
        );
        for y in 0..h {
            for x in 0..w {
                let (x0, x1, y0, y1) = (x.saturating_sub(3), (x + 4).min(w), y.saturating_sub(3), (y + 4).min(h));
                let sum: f64 = (y0..y1)
                    .flat_map(|yy| (x0..x1).map(move |xx| (xx, yy)))
                    .map(|(xx, yy)| f64::from(pixels[yy * w + xx]))
                    .sum();
                let mean = sum / ((x1 - x0) * (y1 - y0)) as f64;
                let v = f64::from(pixels[y * w + x]);
                assert_eq!(mask[y * w + x], v < 0.5 * mean && v + 5.0 < mean, "({x}, {y})");
            }
        }
    }

    #[test]
    fn a_drawn_target_is_found_at_its_centre() {
        for (centre, r) in [([40.3, 31.7], 7.0), ([25.55, 24.1], 2.2), ([30.0, 30.0], 15.0)] {
            let img = draw(80, 64, &[(centre, r)], 120, 1.0);
            let found = detect(&img, 80, 64, &DetectSettings::default());
            assert_eq!(found.len(), 1, "r {r}: {found:?}");
            let d = found[0];
            assert!((d.centre[0] - centre[0]).hypot(d.centre[1] - centre[1]) < 0.05, "r {r}: {d:?}");
            assert!((d.radius_px - r).abs() < 0.25 * r, "r {r}: {d:?}");
            assert!(d.contrast > 150.0, "{d:?}");
        }
    }

    #[test]
    fn small_targets_anywhere_in_a_pixel_are_found_within_a_few_hundredths_of_a_pixel() {
        for r in [1.7, 3.2] {
            let mut sum = 0.0;
            let n = 40;
            for k in 0..n {
                let u = |part| lineflow_photogrammetry::random::unit(lineflow_photogrammetry::random::hash(&[k, part]));
                let centre = [20.0 + u(1), 20.0 + u(2)];
                let found = detect(&draw(40, 40, &[(centre, r)], 120, 1.0), 40, 40, &DetectSettings::default());
                assert_eq!(found.len(), 1, "r {r} at {centre:?}");
                sum += (found[0].centre[0] - centre[0]).powi(2) + (found[0].centre[1] - centre[1]).powi(2);
            }
            let rms = (sum / n as f64).sqrt();
            assert!(rms < 0.03, "r {r}: RMS {rms} px");
        }
    }

    #[test]
    fn an_oblique_target_is_found_and_a_too_oblique_one_is_not() {
        let img = draw(80, 64, &[([40.2, 30.4], 8.0)], 120, 0.5);
        let found = detect(&img, 80, 64, &DetectSettings::default());
        assert_eq!(found.len(), 1);
        assert!((found[0].centre[0] - 40.2).hypot(found[0].centre[1] - 30.4) < 0.05, "{found:?}");
        let img = draw(80, 64, &[([40.2, 30.4], 8.0)], 120, 0.2);
        assert!(detect(&img, 80, 64, &DetectSettings::default()).is_empty());
    }

    #[test]
    fn several_targets_are_found_in_reading_order() {
        let img = draw(120, 80, &[([90.0, 20.0], 5.0), ([30.0, 21.0], 5.0), ([60.0, 60.0], 4.0)], 140, 1.0);
        let found = detect(&img, 120, 80, &DetectSettings::default());
        let centres: Vec<[i64; 2]> = found
            .iter()
            .map(|d| [d.centre[0].round() as i64, d.centre[1].round() as i64])
            .collect();
        assert_eq!(centres, vec![[90, 20], [30, 21], [60, 60]]);
    }

    #[test]
    fn no_target_in_a_blank_wall_noise_a_black_disc_a_bright_square_or_a_cut_target() {
        let s = DetectSettings::default();
        assert!(detect(&[128; 64 * 64], 64, 64, &s).is_empty());
        // Noise of ±40 grey levels.
        let noise: Vec<u8> = (0..64 * 64u64)
            .map(|i| (128 + (lineflow_photogrammetry::random::hash(&[i]) % 81) as i64 - 40) as u8)
            .collect();
        assert!(detect(&noise, 64, 64, &s).is_empty());
        // A black disc without its white centre, and a white square in a black square frame.
        let mut img = vec![150u8; 64 * 64];
        for y in 0..64 {
            for x in 0..64 {
                if (x as f64 - 20.0).hypot(y as f64 - 20.0) < 8.0 {
                    img[y * 64 + x] = 10;
                }
                if (38..58).contains(&x) && (38..58).contains(&y) {
                    img[y * 64 + x] = if (43..53).contains(&x) && (43..53).contains(&y) { 240 } else { 10 };
                }
            }
        }
        assert!(detect(&img, 64, 64, &s).is_empty());
        // A target cut by the image's border.
        let img = draw(40, 40, &[([3.0, 20.0], 5.0)], 120, 1.0);
        assert!(detect(&img, 40, 40, &s).is_empty());
        // A wrong buffer size.
        assert!(detect(&[0; 10], 64, 64, &s).is_empty());
    }

    #[test]
    fn a_dim_target_below_the_least_contrast_is_not_taken() {
        let s = DetectSettings::default();
        let bright = draw_with(64, 64, &[([32.0, 32.0], 6.0)], 120, 1.0, 60.0);
        assert_eq!(detect(&bright, 64, 64, &s).len(), 1, "a disc 50 levels over its ring");
        let dim = draw_with(64, 64, &[([32.0, 32.0], 6.0)], 120, 1.0, 40.0);
        assert!(detect(&dim, 64, 64, &s).is_empty(), "a disc 30 levels over its ring");
    }
}
