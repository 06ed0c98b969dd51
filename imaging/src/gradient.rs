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

/// The planes an edge detector takes its gradient over: one grey image, or the grey image and the three channels of
/// a colour image (each `width × height`), where the gradient at a pixel is that of the plane in which it is
/// strongest. Glass against red brick steps by 60 levels in red and by 12 in grey, below Canny's thresholds.
#[derive(Debug, Clone, Copy)]
pub struct Planes<'a> {
    planes: [&'a [u8]; 4],
    count: usize,
    mode: ColourEdges,
}

/// How an RGB image's channels take part in the gradient: not at all (the grey image's), across plumb edges only,
/// or wherever they are stronger than the grey image's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ColourEdges {
    /// The grey image alone.
    Off,
    /// A channel's gradient where it is stronger, across edges near the image's columns (the plumb edges of a
    /// façade photographed upright), so that level textures that show only in colour (a red roof's tile courses)
    /// stay out.
    #[default]
    Plumb,
    /// A channel's gradient wherever it is stronger.
    All,
}

/// A colour channel's gradient counts across plumb edges only when it points within this angle's tangent of the
/// rows (|gy| ≤ |gx| / 2: edges within 27° of the image's columns).
const PLUMB_GRADIENT_RATIO: i32 = 2;

impl<'a> Planes<'a> {
    /// One grey plane.
    pub fn gray(gray: &'a [u8]) -> Self {
        Planes {
            planes: [gray; 4],
            count: 1,
            mode: ColourEdges::Off,
        }
    }

    /// A grey plane and three channel planes of one size, the channels taking part as `mode` says (`Off`: the grey
    /// plane alone).
    pub fn colour(gray: &'a [u8], r: &'a [u8], g: &'a [u8], b: &'a [u8], mode: ColourEdges) -> Self {
        if mode == ColourEdges::Off {
            return Self::gray(gray);
        }
        Planes {
            planes: [gray, r, g, b],
            count: 4,
            mode,
        }
    }

    /// How the colour channels take part.
    pub fn mode(&self) -> ColourEdges {
        self.mode
    }

    /// The planes.
    pub fn iter(&self) -> impl Iterator<Item = &'a [u8]> + '_ {
        self.planes[..self.count].iter().copied()
    }

    /// Whether a further plane's gradient (`gx`, `gy`, squared magnitude `m2`) replaces one of squared magnitude
    /// `best2`.
    fn stronger(&self, gx: i32, gy: i32, m2: i32, best2: i32) -> bool {
        m2 > best2 && (self.mode != ColourEdges::Plumb || gy.abs() * PLUMB_GRADIENT_RATIO <= gx.abs())
    }

    /// [`gradient_row`] of the strongest plane at each pixel into `out`; `scratch` holds a row's room for the
    /// others.
    pub fn gradient_row(&self, width: usize, height: usize, y: usize, out: GradientRow, scratch: &mut RowScratch) {
        let GradientRow { gx, gy, mag2 } = out;
        gradient_row(self.planes[0], width, height, y, gx, gy, mag2);
        for plane in &self.planes[1..self.count] {
            scratch.resize(width);
            gradient_row(plane, width, height, y, &mut scratch.gx, &mut scratch.gy, &mut scratch.mag2);
            for x in 0..width {
                if self.stronger(scratch.gx[x] as i32, scratch.gy[x] as i32, scratch.mag2[x], mag2[x]) {
                    (gx[x], gy[x], mag2[x]) = (scratch.gx[x], scratch.gy[x], scratch.mag2[x]);
                }
            }
        }
    }

    /// [`gradient_at`] of the strongest plane.
    pub fn gradient_at(&self, width: usize, height: usize, x: usize, y: usize) -> (i32, i32) {
        let mut best = gradient_at(self.planes[0], width, height, x, y);
        for plane in &self.planes[1..self.count] {
            let g = gradient_at(plane, width, height, x, y);
            if self.stronger(g.0, g.1, g.0 * g.0 + g.1 * g.1, best.0 * best.0 + best.1 * best.1) {
                best = g;
            }
        }
        best
    }
}

/// One row of gradient components and squared magnitudes, each `width` long: where [`Planes::gradient_row`] writes.
#[derive(Debug)]
pub struct GradientRow<'a> {
    /// ∂I/∂x.
    pub gx: &'a mut [i16],
    /// ∂I/∂y.
    pub gy: &'a mut [i16],
    /// gx² + gy².
    pub mag2: &'a mut [i32],
}

/// One row's room for a plane's gradient in [`Planes::gradient_row`].
#[derive(Debug, Clone, Default)]
pub struct RowScratch {
    gx: Vec<i16>,
    gy: Vec<i16>,
    mag2: Vec<i32>,
}

impl RowScratch {
    fn resize(&mut self, width: usize) {
        self.gx.resize(width, 0);
        self.gy.resize(width, 0);
        self.mag2.resize(width, 0);
    }
}

/// The three channel planes of an interleaved RGB8 image whose rows are `step` bytes.
pub fn rgb_planes(src: &[u8], width: usize, height: usize, step: usize) -> [Vec<u8>; 3] {
    let mut out = Default::default();
    rgb_planes_into(src, width, height, step, &mut out);
    out
}

/// [`rgb_planes`] into `out`, whose buffers are reused from frame to frame.
pub fn rgb_planes_into(src: &[u8], width: usize, height: usize, step: usize, out: &mut [Vec<u8>; 3]) {
    for plane in out.iter_mut() {
        plane.resize(width * height, 0);
    }
    let [r, g, b] = out;
    for row in 0..height {
        let px = &src[row * step..row * step + width * 3];
        let span = row * width..(row + 1) * width;
        for (((c, r), g), b) in px
            .chunks_exact(3)
            .zip(&mut r[span.clone()])
            .zip(&mut g[span.clone()])
            .zip(&mut b[span])
        {
            (*r, *g, *b) = (c[0], c[1], c[2]);
        }
    }
}
