//! An image's grey values as the appearance test samples them.

/// An image's 8-bit grey values, row-major.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Photo {
    width: usize,
    height: usize,
    gray: Vec<u8>,
}

impl Photo {
    /// The photo of `gray`, if it holds `width × height` values.
    pub fn new(width: usize, height: usize, gray: Vec<u8>) -> Option<Self> {
        (width >= 2 && height >= 2 && gray.len() == width * height).then_some(Photo { width, height, gray })
    }

    /// Bilinear grey value at pixel position `px` (pixel centres at integer + 0.5, as in the conventions), if
    /// inside the image.
    pub fn sample(&self, px: [f64; 2]) -> Option<f32> {
        let (x, y) = (px[0] - 0.5, px[1] - 0.5);
        if !(x >= 0.0 && y >= 0.0 && x < (self.width - 1) as f64 && y < (self.height - 1) as f64) {
            return None;
        }
        let (x0, y0) = (x as usize, y as usize);
        let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
        let at = |c: usize, r: usize| self.gray[r * self.width + c] as f32;
        let top = at(x0, y0) + fx * (at(x0 + 1, y0) - at(x0, y0));
        let bottom = at(x0, y0 + 1) + fx * (at(x0 + 1, y0 + 1) - at(x0, y0 + 1));
        Some(top + fy * (bottom - top))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_samples_at_pixel_centres_and_between() {
        let p = Photo::new(2, 2, vec![0, 100, 200, 50]).unwrap();
        assert_eq!(p.sample([0.5, 0.5]), Some(0.0));
        assert_eq!(p.sample([1.0, 0.5]), Some(50.0));
        assert!((p.sample([1.0, 1.0]).unwrap() - 87.5).abs() < 1e-4);
        assert_eq!(p.sample([0.4, 0.5]), None);
        assert_eq!(p.sample([1.5, 1.5]), None, "the last centre has no neighbour to interpolate with");
        assert!(Photo::new(3, 2, vec![0; 5]).is_none());
    }
}
