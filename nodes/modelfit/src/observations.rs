//! The edge pixels of one oriented image in ideal photo coordinates, binned for buffer queries.
use lineflow_messages::EdgePixel;
use lineflow_photogrammetry::{Camera, Pose};

/// One edge pixel where the fitting sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeObservation {
    /// Ideal photo coordinates (distortion-corrected, relative to the principal point), mm.
    pub xy: [f64; 2],
    /// Unit gradient direction in photo axes (y up).
    pub gradient: [f64; 2],
    /// G / G_max of the image, in [0, 1].
    pub relative: f64,
}

/// An oriented image and its edge pixels.
#[derive(Debug, Clone)]
pub struct ImageEdges {
    /// Interior orientation.
    pub camera: Camera,
    /// Exterior orientation.
    pub pose: Pose,
    observations: Vec<EdgeObservation>,
    /// Cell of side `cell_mm` → range of `order`; cells row-major from `origin`.
    cell_mm: f64,
    origin: [f64; 2],
    cols: usize,
    rows: usize,
    starts: Vec<u32>,
    order: Vec<u32>,
}

/// Cells are 8 pixels wide: a buffer of a few pixels touches a handful, the widest (0.4 mm) a few dozen.
const CELL_PX: f64 = 8.0;

impl ImageEdges {
    /// The edge pixels of one image, in the order given (row-major from the edges stage).
    pub fn new(camera: Camera, pose: Pose, pixels: &[EdgePixel]) -> Self {
        Self::with_positions(camera, pose, pixels, None)
    }

    /// The edge pixels at refined (sub-pixel) positions (col, row), one per pixel, where given.
    pub fn with_positions(camera: Camera, pose: Pose, pixels: &[EdgePixel], positions: Option<&[[f64; 2]]>) -> Self {
        let g_max = pixels.iter().map(|p| p.magnitude).fold(0.0f32, f32::max).max(f32::MIN_POSITIVE) as f64;
        let observations: Vec<EdgeObservation> = pixels
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let (s, c) = (p.direction_rad as f64).sin_cos();
                let at = positions.and_then(|q| q.get(i).copied()).unwrap_or([p.col as f64, p.row as f64]);
                EdgeObservation {
                    xy: camera.pixel_to_ideal(at),
                    // Pixel rows grow downwards, photo y upwards.
                    gradient: [c, -s],
                    relative: (p.magnitude as f64 / g_max).clamp(0.0, 1.0),
                }
            })
            .collect();
        Self::from_observations(camera, pose, observations)
    }

    /// An image from observations already in photo coordinates.
    pub fn from_observations(camera: Camera, pose: Pose, observations: Vec<EdgeObservation>) -> Self {
        let cell_mm = CELL_PX * camera.pixel_size_mm;
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for o in &observations {
            for k in 0..2 {
                lo[k] = lo[k].min(o.xy[k]);
                hi[k] = hi[k].max(o.xy[k]);
            }
        }
        if observations.is_empty() {
            (lo, hi) = ([0.0; 2], [0.0; 2]);
        }
        let cols = ((hi[0] - lo[0]) / cell_mm) as usize + 1;
        let rows = ((hi[1] - lo[1]) / cell_mm) as usize + 1;
        let cell_of = |xy: [f64; 2]| {
            let c = (((xy[0] - lo[0]) / cell_mm) as usize).min(cols - 1);
            let r = (((xy[1] - lo[1]) / cell_mm) as usize).min(rows - 1);
            r * cols + c
        };
        let mut starts = vec![0u32; cols * rows + 1];
        for o in &observations {
            starts[cell_of(o.xy) + 1] += 1;
        }
        for i in 1..starts.len() {
            starts[i] += starts[i - 1];
        }
        let mut fill = starts.clone();
        let mut order = vec![0u32; observations.len()];
        for (i, o) in observations.iter().enumerate() {
            let c = cell_of(o.xy);
            order[fill[c] as usize] = i as u32;
            fill[c] += 1;
        }
        Self {
            camera,
            pose,
            observations,
            cell_mm,
            origin: lo,
            cols,
            rows,
            starts,
            order,
        }
    }

    /// Every observation.
    pub fn observations(&self) -> &[EdgeObservation] {
        &self.observations
    }

    /// Calls `visit` with the index of every observation that may lie within `radius_mm` of segment `p`–`q`
    /// (whole cells, so a superset), in a fixed order.
    pub fn near_segment(&self, p: [f64; 2], q: [f64; 2], radius_mm: f64, mut visit: impl FnMut(usize)) {
        if self.observations.is_empty() {
            return;
        }
        let cell = self.cell_mm;
        let to_cell = |v: f64, o: f64, n: usize| ((v - o) / cell).floor().clamp(-1.0, n as f64) as isize;
        let c0 = to_cell(p[0].min(q[0]) - radius_mm, self.origin[0], self.cols).max(0);
        let c1 = to_cell(p[0].max(q[0]) + radius_mm, self.origin[0], self.cols).min(self.cols as isize - 1);
        let r0 = to_cell(p[1].min(q[1]) - radius_mm, self.origin[1], self.rows).max(0);
        let r1 = to_cell(p[1].max(q[1]) + radius_mm, self.origin[1], self.rows).min(self.rows as isize - 1);
        // A cell can hold a point within the radius only if its centre is within radius + half its diagonal.
        let reach = radius_mm + cell * std::f64::consts::FRAC_1_SQRT_2;
        for r in r0..=r1 {
            for c in c0..=c1 {
                let centre = [self.origin[0] + (c as f64 + 0.5) * cell, self.origin[1] + (r as f64 + 0.5) * cell];
                if point_segment_distance(centre, p, q) > reach {
                    continue;
                }
                let k = r as usize * self.cols + c as usize;
                for &i in &self.order[self.starts[k] as usize..self.starts[k + 1] as usize] {
                    visit(i as usize);
                }
            }
        }
    }
}

/// Distance from `x` to the segment `p`–`q`.
pub fn point_segment_distance(x: [f64; 2], p: [f64; 2], q: [f64; 2]) -> f64 {
    let (tx, ty) = (q[0] - p[0], q[1] - p[1]);
    let len2 = tx * tx + ty * ty;
    let s = if len2 > 0.0 {
        (((x[0] - p[0]) * tx + (x[1] - p[1]) * ty) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((x[0] - p[0] - s * tx).powi(2) + (x[1] - p[1] - s * ty).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_photogrammetry::{rotation_from_opk, Vec3};

    #[test]
    fn segment_query_is_a_superset_of_the_buffer() {
        let camera = Camera::pinhole(400, 300, 0.01, 20.0);
        let pose = Pose {
            center: Vec3::zeros(),
            rotation: rotation_from_opk(0.0, 0.0, 0.0),
        };
        let pixels: Vec<EdgePixel> = (0..300u16)
            .flat_map(|r| (0..400u16).step_by(7).map(move |c| (c, r)))
            .map(|(col, row)| EdgePixel {
                col,
                row,
                magnitude: 1.0 + col as f32,
                direction_rad: 0.3,
            })
            .collect();
        let img = ImageEdges::new(camera, pose, &pixels);
        let (p, q, r) = ([-1.0, -0.5], [1.2, 0.9], 0.05);
        let mut found = Vec::new();
        img.near_segment(p, q, r, |i| found.push(i));
        found.sort();
        let truth: Vec<usize> = (0..img.observations().len())
            .filter(|&i| point_segment_distance(img.observations()[i].xy, p, q) <= r)
            .collect();
        assert!(truth.len() > 50);
        assert!(truth.iter().all(|i| found.binary_search(i).is_ok()));
        assert!(found.len() < img.observations().len() / 3, "the query is local");
        let max = img.observations().iter().map(|o| o.relative).fold(0.0, f64::max);
        assert_eq!(max, 1.0, "seed fact C2: the strongest pixel weighs 1");
        assert!(img.observations().iter().all(|o| (0.0..=1.0).contains(&o.relative)));
    }
}
