//! Integral images: the sum over any axis-aligned rectangle in four look-ups (seed 000 §2.4).

/// Cumulative sums of an 8-bit image with a zero row and column in front, so that `sum(x0, y0, x1, y1)` needs no
/// edge cases. Sums wrap in `u32`: a rectangle's true sum (at most 255 × 16.8 M pixels) fits, so the wrapped
/// differences are exact, at half the memory of `u64`.
#[derive(Debug, Clone)]
pub struct Integral {
    /// Width + 1.
    stride: usize,
    width: usize,
    height: usize,
    sums: Vec<u32>,
}

impl Integral {
    /// The integral image of `pixels` (`width` × `height`, row-major).
    ///
    /// # Panics
    /// When `pixels` is shorter than `width * height` (a caller bug).
    pub fn new(pixels: &[u8], width: usize, height: usize) -> Self {
        Self::in_buffer(pixels, width, height, Vec::new())
    }

    /// [`Integral::new`] in the memory of `buffer` (from [`Integral::into_buffer`]): a 12 MP frame's sums are 49 MB,
    /// and fresh pages cost the kernel's zeroing on every frame.
    ///
    /// # Panics
    /// When `pixels` is shorter than `width * height` (a caller bug).
    pub fn in_buffer(pixels: &[u8], width: usize, height: usize, mut sums: Vec<u32>) -> Self {
        assert!(pixels.len() >= width * height, "{} pixels for {width}x{height}", pixels.len());
        let stride = width + 1;
        sums.clear();
        sums.resize(stride * (height + 1), 0);
        for y in 0..height {
            let (above, rest) = sums.split_at_mut((y + 1) * stride);
            let above = &above[y * stride..];
            let row = &mut rest[..stride];
            let mut acc = 0u32;
            for x in 0..width {
                acc = acc.wrapping_add(pixels[y * width + x] as u32);
                row[x + 1] = above[x + 1].wrapping_add(acc);
            }
        }
        Self {
            stride,
            width,
            height,
            sums,
        }
    }

    /// The memory of the sums, for the next [`Integral::in_buffer`].
    pub fn into_buffer(self) -> Vec<u32> {
        self.sums
    }

    /// Image width.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Image height.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Sum of the pixels with `x0 <= x < x1`, `y0 <= y < y1`, the rectangle clipped to the image.
    #[inline]
    pub fn sum(&self, x0: isize, y0: isize, x1: isize, y1: isize) -> f32 {
        let cx = |x: isize| x.clamp(0, self.width as isize) as usize;
        let cy = |y: isize| y.clamp(0, self.height as isize) as usize;
        let (x0, x1, y0, y1) = (cx(x0), cx(x1), cy(y0), cy(y1));
        if x1 <= x0 || y1 <= y0 {
            return 0.0;
        }
        self.sum_inside(x0, y0, x1, y1) as f32
    }

    /// [`sum`](Self::sum) of a rectangle known to lie inside the image.
    #[inline]
    pub fn sum_inside(&self, x0: usize, y0: usize, x1: usize, y1: usize) -> u32 {
        let s = &self.sums;
        let (a, b) = (y0 * self.stride, y1 * self.stride);
        s[b + x1].wrapping_sub(s[b + x0]).wrapping_sub(s[a + x1]).wrapping_add(s[a + x0])
    }

    /// Haar wavelet response in x of side `size` centred on (x, y): right half minus left half.
    #[inline]
    pub fn haar_x(&self, x: isize, y: isize, size: isize) -> f32 {
        let h = size / 2;
        self.sum(x, y - h, x + h, y + h) - self.sum(x - h, y - h, x, y + h)
    }

    /// Haar wavelet response in y: lower half minus upper half.
    #[inline]
    pub fn haar_y(&self, x: isize, y: isize, size: isize) -> f32 {
        let h = size / 2;
        self.sum(x - h, y, x + h, y + h) - self.sum(x - h, y - h, x + h, y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rectangle_sums_match_brute_force() {
        let (w, h) = (13, 7);
        let px: Vec<u8> = (0..w * h).map(|i| (i * 37 % 251) as u8).collect();
        let ii = Integral::new(&px, w, h);
        let brute = |x0: usize, y0: usize, x1: usize, y1: usize| -> u32 {
            (y0..y1)
                .flat_map(|y| (x0..x1).map(move |x| (x, y)))
                .map(|(x, y)| px[y * w + x] as u32)
                .sum()
        };
        for (x0, y0, x1, y1) in [(0, 0, 13, 7), (2, 1, 5, 6), (12, 6, 13, 7), (3, 3, 3, 5)] {
            assert_eq!(ii.sum_inside(x0, y0, x1, y1), brute(x0, y0, x1, y1));
        }
        assert_eq!(ii.sum(-5, -5, 100, 100), brute(0, 0, 13, 7) as f32, "clipped to the image");
    }

    #[test]
    fn haar_responses_see_a_vertical_edge_in_x_only() {
        let (w, h) = (20, 20);
        let px: Vec<u8> = (0..w * h).map(|i| if i % w >= 10 { 200 } else { 0 }).collect();
        let ii = Integral::new(&px, w, h);
        assert_eq!(ii.haar_x(10, 10, 4), 200.0 * 2.0 * 4.0, "2 columns x 4 rows of 200 on the right");
        assert_eq!(ii.haar_y(10, 10, 4), 0.0);
    }
}
