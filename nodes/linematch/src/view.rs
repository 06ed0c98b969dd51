//! An oriented grey image: pose, camera, a lookup table for the inverse correction, and bilinear sampling.
use lineflow_photogrammetry::{Camera, Pose, Vec3};

use lineflow_linegeom::FrameSegments;

/// Measured pixel positions of ideal photo points on a regular grid, interpolated bilinearly: the inverse correction
/// (`Camera::distort`, Newton iterations) is far too slow for millions of grid samples, and the correction is smooth
/// enough that a 16-pixel grid reproduces it within a few thousandths of a pixel.
#[derive(Debug, Clone)]
pub struct DistortionLut {
    origin: [f64; 2],
    step_mm: f64,
    cols: usize,
    rows: usize,
    /// (col, row) of each node, NaN where the model does not invert.
    nodes: Vec<[f32; 2]>,
}

/// Grid spacing of the lookup table, pixels.
const LUT_STEP_PX: f64 = 16.0;

impl DistortionLut {
    /// The table of `camera`, covering the ideal image of the sensor with a margin of 8 % on each side.
    pub fn new(camera: &Camera) -> Self {
        let (w, h) = (camera.width as f64, camera.height as f64);
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        let border = (0..=32).flat_map(|k| {
            let t = k as f64 / 32.0;
            [[t * w, -0.5], [t * w, h], [-0.5, t * h], [w, t * h]]
        });
        for px in border {
            let i = camera.pixel_to_ideal(px);
            for a in 0..2 {
                lo[a] = lo[a].min(i[a]);
                hi[a] = hi[a].max(i[a]);
            }
        }
        let margin = [0.08 * (hi[0] - lo[0]), 0.08 * (hi[1] - lo[1])];
        let step_mm = LUT_STEP_PX * camera.pixel_size_mm;
        let origin = [lo[0] - margin[0], lo[1] - margin[1]];
        let cols = ((hi[0] + margin[0] - origin[0]) / step_mm).ceil() as usize + 2;
        let rows = ((hi[1] + margin[1] - origin[1]) / step_mm).ceil() as usize + 2;
        let mut nodes = Vec::with_capacity(cols * rows);
        for r in 0..rows {
            for c in 0..cols {
                let ideal = [origin[0] + c as f64 * step_mm, origin[1] + r as f64 * step_mm];
                nodes.push(match camera.ideal_to_pixel(ideal) {
                    Some(p) => [p[0] as f32, p[1] as f32],
                    None => [f32::NAN; 2],
                });
            }
        }
        DistortionLut {
            origin,
            step_mm,
            cols,
            rows,
            nodes,
        }
    }

    /// Measured pixel position of an ideal photo point (mm, relative to the principal point); NaN outside the table.
    #[inline]
    pub fn pixel(&self, ideal: [f64; 2]) -> [f32; 2] {
        let gx = (ideal[0] - self.origin[0]) / self.step_mm;
        let gy = (ideal[1] - self.origin[1]) / self.step_mm;
        if !(gx >= 0.0 && gy >= 0.0) {
            return [f32::NAN; 2];
        }
        let (c, r) = (gx as usize, gy as usize);
        if c + 1 >= self.cols || r + 1 >= self.rows {
            return [f32::NAN; 2];
        }
        let (fx, fy) = ((gx - c as f64) as f32, (gy - r as f64) as f32);
        let at = |r: usize, c: usize| self.nodes[r * self.cols + c];
        let (a, b, d, e) = (at(r, c), at(r, c + 1), at(r + 1, c), at(r + 1, c + 1));
        std::array::from_fn(|k| {
            let top = a[k] + fx * (b[k] - a[k]);
            let bottom = d[k] + fx * (e[k] - d[k]);
            top + fy * (bottom - top)
        })
    }
}

/// One oriented grey image.
#[derive(Debug, Clone)]
pub struct View<'a> {
    /// Frame number.
    pub frame: u64,
    /// Exterior orientation.
    pub pose: Pose,
    /// Interior orientation.
    pub camera: Camera,
    /// Inverse correction table of `camera`.
    pub lut: &'a DistortionLut,
    /// 8-bit grey pixels, row-major, `camera.width × camera.height`.
    pub gray: &'a [u8],
    /// The frame's own 2-D segments, when it serves as a slave whose lines refine the depths.
    pub segments: Option<&'a FrameSegments>,
}

impl View<'_> {
    /// Bilinear grey value at a measured pixel position (eq. 16), NaN outside the image.
    #[inline]
    pub fn sample(&self, px: [f32; 2]) -> f32 {
        let (w, h) = (self.camera.width as usize, self.camera.height as usize);
        lineflow_imaging::bilinear(self.gray, w, h, px[0], px[1])
    }

    /// [`sample`](Self::sample) from 16.16 fixed-point coordinates the caller knows to satisfy `0 ≤ x < width − 1`
    /// and `0 ≤ y < height − 1`: one bounds check instead of four, no NaN test, and the interpolation in integers
    /// with 8-bit weights (1/256 px), which is most of a lattice sample's cost.
    #[inline]
    fn sample_fixed(&self, x: i32, y: i32) -> f32 {
        let w = self.camera.width as usize;
        let (c, r) = ((x >> 16) as usize, (y >> 16) as usize);
        let (fx, fy) = ((x >> 8) & 0xFF, (y >> 8) & 0xFF);
        let i = r * w + c;
        let g = &self.gray[i..i + w + 2];
        let (a, b, d, e) = (g[0] as i32, g[1] as i32, g[w] as i32, g[w + 1] as i32);
        let top = (a << 8) + fx * (b - a);
        let bottom = (d << 8) + fx * (e - d);
        ((top << 8) + fy * (bottom - top)) as f32 * (1.0 / 65536.0)
    }

    /// Whether the bilinear neighbourhood of every point of the convex hull of `corners` lies in the image, with a
    /// margin for the rounding of the interpolated positions.
    fn cell_inside(&self, corners: [[f32; 2]; 4]) -> bool {
        const MARGIN: f32 = 0.01;
        let (w, h) = (self.camera.width as f32 - 1.0 - MARGIN, self.camera.height as f32 - 1.0 - MARGIN);
        corners.iter().all(|q| q[0] >= MARGIN && q[0] < w && q[1] >= MARGIN && q[1] < h)
    }

    /// The measured pixel position of the lattice node `base + i·da + j·dc` (in the camera frame), NaN when it is
    /// behind the camera or beyond the correction model.
    #[inline]
    fn node_pixel(&self, base: &Vec3, da: &Vec3, dc: &Vec3, i: f64, j: f64) -> [f32; 2] {
        let p = base + da * i + dc * j;
        if p.z >= 0.0 {
            return [f32::NAN; 2];
        }
        let s = -self.camera.focal_mm / p.z;
        self.lut.pixel([s * p.x, s * p.y])
    }

    /// Samples the lattice `origin + i·along + j·across` for `i` in `cols`, `j` in `rows` (row-major, `j` outer) into
    /// `out`: the object-space patch of the thesis, resampled through the full camera model. NaN where a node is
    /// behind the camera or outside the image.
    ///
    /// The lattice-to-image map (a plane's perspective projection, then the smooth correction model) is evaluated
    /// exactly every [`NODE_STEP`] nodes in each direction and interpolated bilinearly in between, within a few
    /// thousandths of a pixel: the projection and the inverse correction otherwise cost more than the sampling.
    pub fn sample_lattice(&self, origin: &Vec3, along: &Vec3, across: &Vec3, cols: (i32, i32), rows: (i32, i32), out: &mut Vec<f32>) {
        let m = &self.pose.rotation;
        let base = m * (origin - self.pose.center);
        let (da, dc) = (m * along, m * across);
        let (nc, nr) = ((cols.1 - cols.0 + 1) as usize, (rows.1 - rows.0 + 1) as usize);
        // Exact positions on the coarse nodes (the last column and row always included).
        let coarse = |n: usize| (n - 1).div_ceil(NODE_STEP) + 1;
        let (gc, gr) = (coarse(nc), coarse(nr));
        let at = |k: usize, n: usize| (k * NODE_STEP).min(n - 1);
        let mut nodes = Vec::with_capacity(gc * gr);
        for r in 0..gr {
            let j = (rows.0 + at(r, nr) as i32) as f64;
            for c in 0..gc {
                let i = (cols.0 + at(c, nc) as i32) as f64;
                nodes.push(self.node_pixel(&base, &da, &dc, i, j));
            }
        }
        out.clear();
        out.resize(nc * nr, f32::NAN);
        for r in 0..gr.saturating_sub(1) {
            let (j0, j1) = (at(r, nr), at(r + 1, nr));
            for c in 0..gc.saturating_sub(1) {
                let (i0, i1) = (at(c, nc), at(c + 1, nc));
                let (a, b) = (nodes[r * gc + c], nodes[r * gc + c + 1]);
                let (d, e) = (nodes[(r + 1) * gc + c], nodes[(r + 1) * gc + c + 1]);
                if [a, b, d, e].iter().any(|q| q[0].is_nan()) {
                    continue;
                }
                let last_row = r + 2 == gr;
                let last_col = c + 2 == gc;
                let inside = self.cell_inside([a, b, d, e]);
                let span = (i1 - i0).max(1) as f32;
                let end = if last_col { i1 + 1 } else { i1 };
                for j in j0..(if last_row { j1 + 1 } else { j1 }) {
                    let fy = (j - j0) as f32 / (j1 - j0).max(1) as f32;
                    let left = [a[0] + fy * (d[0] - a[0]), a[1] + fy * (d[1] - a[1])];
                    let step = [
                        (b[0] + fy * (e[0] - b[0]) - left[0]) / span,
                        (b[1] + fy * (e[1] - b[1]) - left[1]) / span,
                    ];
                    let row = &mut out[j * nc + i0..j * nc + end];
                    if inside {
                        // 16.16 fixed point along the row: integer steps instead of two float-to-integer conversions
                        // per sample; the rounding (2⁻¹⁶ px per step) is far below what the NCC resolves.
                        const ONE: f32 = 65536.0;
                        let (mut x, mut y) = ((left[0] * ONE) as i32, (left[1] * ONE) as i32);
                        let (dx, dy) = ((step[0] * ONE) as i32, (step[1] * ONE) as i32);
                        for v in row {
                            *v = self.sample_fixed(x, y);
                            x += dx;
                            y += dy;
                        }
                    } else {
                        for (k, v) in row.iter_mut().enumerate() {
                            let k = k as f32;
                            *v = self.sample([left[0] + k * step[0], left[1] + k * step[1]]);
                        }
                    }
                }
            }
        }
        // A lattice of one row or one column has no cells: sample its nodes directly.
        if gr == 1 || gc == 1 {
            for r in 0..nr {
                for c in 0..nc {
                    let px = self.node_pixel(&base, &da, &dc, (cols.0 + c as i32) as f64, (rows.0 + r as i32) as f64);
                    out[r * nc + c] = self.sample(px);
                }
            }
        }
    }
}

/// Spacing of the exactly projected lattice nodes in [`View::sample_lattice`].
pub const NODE_STEP: usize = 8;

#[cfg(test)]
mod tests {
    use super::*;

    /// The A55's strongly distorted corners (about 494 µm of radial correction) on a sensor of the given size.
    fn distorted(width: u32, height: u32, pixel_size_mm: f64) -> Camera {
        Camera {
            width,
            height,
            pixel_size_mm,
            focal_mm: 16.5,
            principal_point_mm: [0.05, -0.03],
            radial: [2.2e-4, -4.0e-7, 0.0],
            decentering: [4.0e-6, -3.0e-6],
        }
    }

    #[test]
    fn interpolated_lattice_samples_equal_exact_projection() {
        let camera = distorted(600, 400, 0.03);
        let lut = DistortionLut::new(&camera);
        // A smooth ramp image so that sample differences reflect position differences.
        let gray: Vec<u8> = (0..600 * 400).map(|k| ((k % 600) / 3 + (k / 600) / 4) as u8).collect();
        let pose = Pose {
            center: Vec3::new(2.0, -12.0, 1.5),
            rotation: lineflow_photogrammetry::rotation_from_opk(std::f64::consts::FRAC_PI_2 + 0.05, 0.1, 0.02),
        };
        let view = View {
            frame: 0,
            pose,
            camera,
            lut: &lut,
            gray: &gray,
            segments: None,
        };
        let (origin, along, across) = (Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.01, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.01));
        let mut fast = Vec::new();
        view.sample_lattice(&origin, &along, &across, (-20, 117), (-21, 21), &mut fast);
        let m = &view.pose.rotation;
        let base = m * (origin - view.pose.center);
        let (mut worst, mut finite) = (0.0f32, 0);
        for (k, j) in (-21..=21).enumerate() {
            for (l, i) in (-20..=117).enumerate() {
                let exact = view.sample(view.node_pixel(&base, &(m * along), &(m * across), i as f64, j as f64));
                let got = fast[k * 138 + l];
                assert_eq!(exact.is_nan(), got.is_nan(), "node ({i}, {j})");
                if exact.is_finite() {
                    worst = worst.max((exact - got).abs());
                    finite += 1;
                }
            }
        }
        assert!(finite > 5000, "only {finite} nodes in the image");
        // The ramp changes by 1/3 grey level per pixel: 0.01 grey level is 0.03 px.
        assert!(worst < 0.01, "worst {worst}");
    }

    #[test]
    fn the_lookup_table_agrees_with_the_exact_inverse_correction() {
        let camera = distorted(4912, 3264, 0.0048);
        let lut = DistortionLut::new(&camera);
        let mut worst = 0.0f64;
        for r in (0..camera.height).step_by(97) {
            for c in (0..camera.width).step_by(89) {
                let px = [c as f64, r as f64];
                let back = lut.pixel(camera.pixel_to_ideal(px));
                worst = worst.max((back[0] as f64 - px[0]).hypot(back[1] as f64 - px[1]));
            }
        }
        assert!(worst < 0.02, "worst {worst} px");
    }
}
