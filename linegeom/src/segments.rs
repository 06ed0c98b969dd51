//! 2-D segments of one oriented image in ideal photo coordinates (where lines are straight), bucketed by a coarse
//! grid so that the segments near a projected 3-D line are found without a scan.
use lineflow_messages::Segment2;
use lineflow_photogrammetry::{Camera, Pose};
/// One frame's 2-D segments in ideal photo coordinates (mm), bucketed by a coarse grid for window queries.
#[derive(Debug, Clone, Default)]
pub struct FrameSegments {
    /// Endpoints of each kept segment, ideal mm.
    pub ends: Vec<[[f64; 2]; 2]>,
    /// Unit direction of each segment (start to end).
    dirs: Vec<[f64; 2]>,
    /// Inclusive cell range (c0, r0, c1, r1) each segment is listed in.
    spans: Vec<[u32; 4]>,
    /// Grid origin (ideal mm), cell size (mm) and size in cells.
    origin: [f64; 2],
    cell_mm: f64,
    cols: usize,
    rows: usize,
    /// Segment indices per cell, row-major.
    cells: Vec<Vec<u32>>,
    /// One pixel, mm.
    pub pixel_mm: f64,
}

/// Grid cell, pixels: a segment lands in the cells its bounding box covers.
const CELL_PX: f64 = 16.0;

impl FrameSegments {
    /// The segments of at least `min_length_px`, endpoints corrected to ideal photo coordinates (where 2-D lines
    /// are straight).
    pub fn new(camera: &Camera, segments: &[Segment2], min_length_px: f64) -> Self {
        let ends: Vec<[[f64; 2]; 2]> = segments
            .iter()
            .filter(|s| (s.end_px[0] - s.start_px[0]).hypot(s.end_px[1] - s.start_px[1]) >= min_length_px)
            .map(|s| [camera.pixel_to_ideal(s.start_px), camera.pixel_to_ideal(s.end_px)])
            .filter(|e| e.iter().flatten().all(|v| v.is_finite()))
            .collect();
        let pixel_mm = camera.pixel_size_mm;
        let cell_mm = CELL_PX * pixel_mm;
        let (w, h) = (camera.width as f64, camera.height as f64);
        let bounds = [[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]].map(|px| camera.pixel_to_ideal(px));
        let lo = |k: usize| bounds.iter().map(|b| b[k]).fold(f64::INFINITY, f64::min);
        let hi = |k: usize| bounds.iter().map(|b| b[k]).fold(f64::NEG_INFINITY, f64::max);
        let origin = [lo(0), lo(1)];
        let size = |k: usize| (((hi(k) - lo(k)) / cell_mm).ceil() as usize).clamp(1, 4096);
        let (cols, rows) = (size(0), size(1));
        let mut frame = FrameSegments {
            ends: Vec::new(),
            dirs: ends.iter().map(|e| unit([e[1][0] - e[0][0], e[1][1] - e[0][1]])).collect(),
            spans: Vec::with_capacity(ends.len()),
            origin,
            cell_mm,
            cols,
            rows,
            cells: vec![Vec::new(); cols * rows],
            pixel_mm,
        };
        for (k, e) in ends.iter().enumerate() {
            let (c0, r0, c1, r1) = frame.cell_range(e[0], e[1], 0.0);
            frame.spans.push([c0, r0, c1, r1].map(|v| v as u32));
            for r in r0..=r1 {
                for c in c0..=c1 {
                    frame.cells[r * cols + c].push(k as u32);
                }
            }
        }
        frame.ends = ends;
        frame
    }

    /// Inclusive cell range (c0, r0, c1, r1) of the box around two points grown by `margin` mm, clamped to the grid.
    fn cell_range(&self, a: [f64; 2], b: [f64; 2], margin: f64) -> (usize, usize, usize, usize) {
        let cell = |v: f64, o: f64, n: usize| (((v - o) / self.cell_mm).floor().max(0.0) as usize).min(n - 1);
        let (x0, x1) = (a[0].min(b[0]) - margin, a[0].max(b[0]) + margin);
        let (y0, y1) = (a[1].min(b[1]) - margin, a[1].max(b[1]) + margin);
        (
            cell(x0, self.origin[0], self.cols),
            cell(y0, self.origin[1], self.rows),
            cell(x1, self.origin[0], self.cols),
            cell(y1, self.origin[1], self.rows),
        )
    }

    /// Segments within `max_angle` (radians) of the direction a→b whose bounding boxes come within `margin` mm of
    /// the box of a and b, each once, in index order.
    pub fn near(&self, a: [f64; 2], b: [f64; 2], margin: f64, max_angle: f64) -> Vec<usize> {
        let dir = unit([b[0] - a[0], b[1] - a[1]]);
        let cos_max = max_angle.cos();
        let any_angle = max_angle >= std::f64::consts::FRAC_PI_2;
        let (c0, r0, c1, r1) = self.cell_range(a, b, margin);
        let mut out = Vec::new();
        for r in r0..=r1 {
            for c in c0..=c1 {
                for &k in &self.cells[r * self.cols + c] {
                    let k = k as usize;
                    // A segment listed in several cells of the window is taken from the first of them only.
                    let s = self.spans[k];
                    if c != (s[0] as usize).max(c0) || r != (s[1] as usize).max(r0) {
                        continue;
                    }
                    let d = self.dirs[k];
                    if any_angle || (d[0] * dir[0] + d[1] * dir[1]).abs() >= cos_max {
                        out.push(k);
                    }
                }
            }
        }
        out.sort_unstable();
        out
    }
}

/// The unit vector along `v` (a zero vector stays zero).
pub fn unit(v: [f64; 2]) -> [f64; 2] {
    let n = v[0].hypot(v[1]).max(1e-300);
    [v[0] / n, v[1] / n]
}

/// A slave with its segments.
#[derive(Debug, Clone, Copy)]
pub struct SlaveSegments<'a> {
    /// The slave's exterior orientation.
    pub pose: Pose,
    /// Its segments.
    pub segments: &'a FrameSegments,
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_photogrammetry::random::Rng;

    /// What `near` promises, by a scan of every segment: bounding boxes within the margin of the window's box and
    /// directions within the angle, each once, in index order.
    fn scanned(f: &FrameSegments, a: [f64; 2], b: [f64; 2], margin: f64, max_angle: f64) -> Vec<usize> {
        let dir = unit([b[0] - a[0], b[1] - a[1]]);
        let (c0, r0, c1, r1) = f.cell_range(a, b, margin);
        (0..f.ends.len())
            .filter(|&k| {
                let s = f.spans[k];
                s[0] as usize <= c1 && s[2] as usize >= c0 && s[1] as usize <= r1 && s[3] as usize >= r0
            })
            .filter(|&k| {
                let e = f.ends[k];
                let d = unit([e[1][0] - e[0][0], e[1][1] - e[0][1]]);
                max_angle >= std::f64::consts::FRAC_PI_2 || (d[0] * dir[0] + d[1] * dir[1]).abs() >= max_angle.cos()
            })
            .collect()
    }

    #[test]
    fn a_window_query_finds_each_segment_of_its_cells_once_in_index_order() {
        let camera = Camera::pinhole(800, 600, 0.01, 10.0);
        let mut rng = Rng::new(7, 0);
        let segments: Vec<Segment2> = (0..2000)
            .map(|id| {
                let start_px = [rng.uniform(0.0, 800.0), rng.uniform(0.0, 600.0)];
                let (angle, length) = (rng.uniform(0.0, std::f64::consts::PI), rng.uniform(5.0, 300.0));
                Segment2 {
                    id,
                    chain_start: 0,
                    chain_len: 0,
                    reserved: 0,
                    start_px,
                    end_px: [start_px[0] + length * angle.cos(), start_px[1] + length * angle.sin()],
                }
            })
            .collect();
        let f = FrameSegments::new(&camera, &segments, 10.0);
        assert!(f.ends.len() > 1500);
        for _ in 0..200 {
            let a = [rng.uniform(-4.0, 4.0), rng.uniform(-3.0, 3.0)];
            let b = [a[0] + rng.uniform(-2.0, 2.0), a[1] + rng.uniform(-2.0, 2.0)];
            let (margin, angle) = (rng.uniform(0.0, 0.1), [0.03, 0.3, std::f64::consts::FRAC_PI_2][rng.below(3)]);
            let found = f.near(a, b, margin, angle);
            assert_eq!(found, scanned(&f, a, b, margin, angle));
        }
    }
}
