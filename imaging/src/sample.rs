//! Bilinear grey values between pixel centres.

/// Bilinear grey value of the row-major 8-bit image `gray` (`width × height`) at `(x, y)`, pixel centres at integer
/// values (`docs/conventions.md`); NaN where the four neighbours are not all inside the image.
#[inline]
pub fn bilinear(gray: &[u8], width: usize, height: usize, x: f32, y: f32) -> f32 {
    if !(x >= 0.0 && y >= 0.0) {
        return f32::NAN;
    }
    let (c, r) = (x as usize, y as usize);
    if c + 1 >= width || r + 1 >= height {
        return f32::NAN;
    }
    let (fx, fy) = (x - c as f32, y - r as f32);
    let i = r * width + c;
    let (a, b, d, e) = (
        gray[i] as f32,
        gray[i + 1] as f32,
        gray[i + width] as f32,
        gray[i + width + 1] as f32,
    );
    let top = a + fx * (b - a);
    let bottom = d + fx * (e - d);
    top + fy * (bottom - top)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centres_at_integers_and_nothing_past_the_last_centre() {
        let g = [0, 100, 200, 50];
        assert_eq!(bilinear(&g, 2, 2, 0.0, 0.0), 0.0);
        assert_eq!(bilinear(&g, 2, 2, 0.5, 0.0), 50.0);
        assert!((bilinear(&g, 2, 2, 0.5, 0.5) - 87.5).abs() < 1e-4);
        assert!(bilinear(&g, 2, 2, -0.1, 0.0).is_nan());
        assert!(
            bilinear(&g, 2, 2, 1.0, 1.0).is_nan(),
            "the last centre has no neighbour to interpolate with"
        );
    }
}
