//! 2-D segments of one oriented image in ideal photo coordinates (where lines are straight), bucketed by a coarse
//! grid so that the segments near a projected 3-D line are found without a scan.
use lineflow_messages::Segment2;
use lineflow_photogrammetry::{Camera, Pose};
/// One frame's 2-D segments in ideal photo coordinates (mm), bucketed by a coarse grid for window queries.
#[derive(Debug, Clone, Default)]
pub struct FrameSegments {
    /// Endpoints of each kept segment, ideal mm.
    pub ends: Vec<[[f64; 2]; 2]>,
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
const CELL_PX: f64 = 64.0;

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
            origin,
            cell_mm,
            cols,
            rows,
            cells: vec![Vec::new(); cols * rows],
            pixel_mm,
        };
        for (k, e) in ends.iter().enumerate() {
            let (c0, r0, c1, r1) = frame.cell_range(e[0], e[1], 0.0);
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
        let (c0, r0, c1, r1) = self.cell_range(a, b, margin);
        let mut out: Vec<usize> = (r0..=r1)
            .flat_map(|r| (c0..=c1).flat_map(move |c| self.cells[r * self.cols + c].iter().map(|&k| k as usize)))
            .collect();
        out.sort_unstable();
        out.dedup();
        out.retain(|&k| {
            let [p, q] = self.ends[k];
            let d = unit([q[0] - p[0], q[1] - p[1]]);
            (d[0] * dir[0] + d[1] * dir[1]).abs() >= cos_max
        });
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
