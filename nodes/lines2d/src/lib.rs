//! Line tracing (`seeds/000_spec.md` §2.7): from a seed edge pixel, follow 8-neighbours that stay within a
//! perpendicular distance of the current line (through the first two pixels, then the total-least-squares line
//! of all once more than three are stacked), in both directions, and keep chains of a minimum length. Lines are
//! fitted in **corrected** coordinates, so a straight edge bent by distortion stays one segment.
#![warn(missing_docs)]

/// Tracing parameters.
#[derive(Debug, Clone, Copy)]
pub struct TraceParams {
    /// Largest perpendicular distance of a new pixel from the current line, pixels.
    pub max_distance_px: f64,
    /// Shortest segment kept, pixels (the thesis: 100 for the D2X, 50 for the A55, at full size).
    pub min_length_px: f64,
}

impl Default for TraceParams {
    fn default() -> Self {
        TraceParams {
            max_distance_px: 1.0,
            min_length_px: 20.0,
        }
    }
}

/// A traced segment: its chain of pixels from one end to the other and its endpoints in corrected coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct Traced {
    /// (col, row) of every pixel, ordered along the segment.
    pub chain: Vec<[u16; 2]>,
    /// First endpoint, corrected pixel coordinates (the chain's first pixel projected on the fitted line).
    pub start: [f64; 2],
    /// Second endpoint, corrected pixel coordinates.
    pub end: [f64; 2],
}

/// Running sums of a total-least-squares line.
#[derive(Debug, Clone, Copy, Default)]
struct Fit {
    n: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
}

impl Fit {
    fn add(&mut self, p: [f64; 2]) {
        self.n += 1.0;
        self.sx += p[0];
        self.sy += p[1];
        self.sxx += p[0] * p[0];
        self.sxy += p[0] * p[1];
        self.syy += p[1] * p[1];
    }
    /// Centroid and unit direction of the principal axis.
    fn line(&self) -> ([f64; 2], [f64; 2]) {
        let c = [self.sx / self.n, self.sy / self.n];
        let a = self.sxx / self.n - c[0] * c[0];
        let b = self.sxy / self.n - c[0] * c[1];
        let d = self.syy / self.n - c[1] * c[1];
        let theta = 0.5 * (2.0 * b).atan2(a - d);
        (c, [theta.cos(), theta.sin()])
    }
}

/// The current constraint line: through the first two pixels until more than three are stacked, then the fit.
fn constraint(points: &[[f64; 2]], fit: &Fit) -> Option<([f64; 2], [f64; 2])> {
    match points.len() {
        0 | 1 => None,
        2..=3 => {
            let (a, b) = (points[0], points[1]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let n = d[0].hypot(d[1]);
            (n > 0.0).then(|| (a, [d[0] / n, d[1] / n]))
        }
        _ => Some(fit.line()),
    }
}

const NEIGHBOURS: [(i32, i32); 8] = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1)];

/// Traces the edge pixels (`pixels`, in raster order) of a `width × height` image. `corrected[i]` holds the
/// corrected coordinates of `pixels[i]`.
pub fn trace(width: usize, height: usize, pixels: &[[u16; 2]], corrected: &[[f64; 2]], p: &TraceParams) -> Vec<Traced> {
    const NONE: u32 = u32::MAX;
    let mut index = vec![NONE; width * height];
    for (i, px) in pixels.iter().enumerate() {
        let (c, r) = (px[0] as usize, px[1] as usize);
        if c < width && r < height {
            index[r * width + c] = i as u32;
        }
    }
    let mut visited = vec![false; pixels.len()];
    let mut out = Vec::new();
    for seed in 0..pixels.len() {
        if visited[seed] || index[pixels[seed][1] as usize * width + pixels[seed][0] as usize] != seed as u32 {
            continue;
        }
        visited[seed] = true;
        let mut fit = Fit::default();
        fit.add(corrected[seed]);
        // Points in the order they were stacked (for the first-two-points constraint) and the two arms.
        let mut stacked = vec![corrected[seed]];
        let mut arms: [Vec<u32>; 2] = [Vec::new(), Vec::new()];
        // Direction of travel of the first arm's first step; the second arm leaves the seed the opposite way.
        let mut first_step: Option<[f64; 2]> = None;
        for (arm, arm_pixels) in arms.iter_mut().enumerate() {
            let mut end = seed as u32;
            let mut heading: Option<[f64; 2]> = if arm == 1 { first_step.map(|h| [-h[0], -h[1]]) } else { None };
            loop {
                let (ec, er) = (pixels[end as usize][0] as i32, pixels[end as usize][1] as i32);
                let line = constraint(&stacked, &fit);
                let here = corrected[end as usize];
                let mut best: Option<(f64, u32)> = None;
                for (dc, dr) in NEIGHBOURS {
                    let (c, r) = (ec + dc, er + dr);
                    if c < 0 || r < 0 || c >= width as i32 || r >= height as i32 {
                        continue;
                    }
                    let j = index[r as usize * width + c as usize];
                    if j == NONE || visited[j as usize] {
                        continue;
                    }
                    let q = corrected[j as usize];
                    let step = [q[0] - here[0], q[1] - here[1]];
                    // Onwards only: a step must not turn back against the arm's heading.
                    if heading.is_some_and(|h| h[0] * step[0] + h[1] * step[1] <= 0.0) {
                        continue;
                    }
                    let score = match line {
                        None => 0.0,
                        Some((o, d)) => {
                            let dist = ((q[0] - o[0]) * d[1] - (q[1] - o[1]) * d[0]).abs();
                            if dist > p.max_distance_px {
                                continue;
                            }
                            dist
                        }
                    };
                    if best.is_none_or(|b| score < b.0) {
                        best = Some((score, j));
                    }
                }
                let Some((_, j)) = best else { break };
                let q = corrected[j as usize];
                let step = [q[0] - here[0], q[1] - here[1]];
                // The heading follows the line (oriented the way the arm travels) once there is one.
                heading = Some(match line {
                    Some((_, d)) if d[0] * step[0] + d[1] * step[1] < 0.0 => [-d[0], -d[1]],
                    Some((_, d)) => d,
                    None => step,
                });
                if arm == 0 && first_step.is_none() {
                    first_step = Some(step);
                }
                visited[j as usize] = true;
                fit.add(corrected[j as usize]);
                stacked.push(corrected[j as usize]);
                arm_pixels.push(j);
                end = j;
            }
        }
        let mut chain: Vec<u32> = arms[1].iter().rev().copied().collect();
        chain.push(seed as u32);
        chain.extend(&arms[0]);
        if chain.len() < 2 {
            continue;
        }
        let (c, d) = fit.line();
        let t = |i: u32| {
            let q = corrected[i as usize];
            (q[0] - c[0]) * d[0] + (q[1] - c[1]) * d[1]
        };
        let (t0, t1) = (t(chain[0]), t(*chain.last().unwrap_or(&chain[0])));
        if (t1 - t0).abs() < p.min_length_px {
            continue;
        }
        out.push(Traced {
            chain: chain.iter().map(|&i| pixels[i as usize]).collect(),
            start: [c[0] + d[0] * t0, c[1] + d[1] * t0],
            end: [c[0] + d[0] * t1, c[1] + d[1] * t1],
        });
    }
    out
}
