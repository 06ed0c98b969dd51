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

    /// Bilinear grey value at pixel position `px` (pixel centres at integer values, as in the conventions), if
    /// inside the image.
    pub fn sample(&self, px: [f64; 2]) -> Option<f32> {
        let v = lineflow_imaging::bilinear(&self.gray, self.width, self.height, px[0] as f32, px[1] as f32);
        (!v.is_nan()).then_some(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_samples_at_pixel_centres_and_between() {
        let p = Photo::new(2, 2, vec![0, 100, 200, 50]).unwrap();
        assert_eq!(p.sample([0.0, 0.0]), Some(0.0));
        assert_eq!(p.sample([0.5, 0.0]), Some(50.0));
        assert!((p.sample([0.5, 0.5]).unwrap() - 87.5).abs() < 1e-4);
        assert_eq!(p.sample([-0.1, 0.0]), None);
        assert_eq!(p.sample([1.0, 1.0]), None, "the last centre has no neighbour to interpolate with");
        assert!(Photo::new(3, 2, vec![0; 5]).is_none());
    }
}
