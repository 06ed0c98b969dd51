//! Implementation `lsd`: the line segment detector of Grompone von Gioi et al. (IPOL 2012), from the `lsdetect`
//! crate, on the grey image; each segment gets the pixel chain of its rasterised centre line, so the later stages
//! see the same Lines2D as from `trace`. LSD works in measured pixels: a long line bent by distortion near the image
//! corners comes out as several segments (`trace` fits in corrected coordinates and does not break it).

/// A detected segment: endpoints in measured pixels (pixel centres at integers) and its ordered pixel chain.
#[derive(Debug, Clone, PartialEq)]
pub struct LsdSegment {
    /// First endpoint.
    pub start: [f64; 2],
    /// Second endpoint.
    pub end: [f64; 2],
    /// Pixels along the segment, in order, each once.
    pub chain: Vec<[u16; 2]>,
}

/// The segments of at least `min_length_px` in an 8-bit grey image.
pub fn lsd(gray: &[u8], width: usize, height: usize, min_length_px: f64) -> Vec<LsdSegment> {
    let Ok(found) = lsdetect::detect(gray, width, height, lsdetect::SCALE) else {
        return Vec::new();
    };
    found
        .iter()
        .filter_map(|s| {
            // lsdetect puts pixel (x, y) on [x, x + 1): its centre is at x + 0.5.
            let (a, b) = ([s.x1 - 0.5, s.y1 - 0.5], [s.x2 - 0.5, s.y2 - 0.5]);
            let length = (b[0] - a[0]).hypot(b[1] - a[1]);
            (length >= min_length_px).then(|| LsdSegment {
                start: a,
                end: b,
                chain: raster(a, b, width, height),
            })
        })
        .collect()
}

/// The pixels a segment passes, sampled every half pixel along it, consecutive duplicates removed.
fn raster(a: [f64; 2], b: [f64; 2], width: usize, height: usize) -> Vec<[u16; 2]> {
    let n = ((b[0] - a[0]).hypot(b[1] - a[1]) * 2.0).ceil().max(1.0) as usize;
    let mut out: Vec<[u16; 2]> = Vec::with_capacity(n / 2 + 1);
    for k in 0..=n {
        let t = k as f64 / n as f64;
        let (x, y) = ((a[0] + t * (b[0] - a[0])).round(), (a[1] + t * (b[1] - a[1])).round());
        if x < 0.0 || y < 0.0 || x >= width as f64 || y >= height as f64 {
            continue;
        }
        let p = [x as u16, y as u16];
        if out.last() != Some(&p) {
            out.push(p);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_edge_is_one_segment_at_the_edge_with_a_connected_chain() {
        let (w, h) = (96, 96);
        let mut image = vec![50u8; w * h];
        image.chunks_mut(w).for_each(|row| row[48..].fill(200));
        let segs = lsd(&image, w, h, 20.0);
        assert_eq!(segs.len(), 1, "{segs:?}");
        let s = &segs[0];
        // The edge lies between columns 47 and 48.
        assert!((s.start[0] - 47.5).abs() < 0.3 && (s.end[0] - 47.5).abs() < 0.3, "{s:?}");
        assert!(s
            .chain
            .windows(2)
            .all(|p| (p[0][0] as i32 - p[1][0] as i32).abs() <= 1 && (p[0][1] as i32 - p[1][1] as i32).abs() <= 1));
        assert!(s.chain.len() > 80);
        assert!(lsd(&image, w, h, 200.0).is_empty(), "shorter than the minimum");
    }
}
