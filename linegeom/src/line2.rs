//! A 2-D line through two points of an image, for the distances and overlaps of segments against it.

/// A 2-D line in ideal photo coordinates from `a` to `b`, for distances and overlaps of segments against it.
#[derive(Debug, Clone, Copy)]
pub struct Line2 {
    a: [f64; 2],
    dir: [f64; 2],
    /// Length, mm.
    pub len: f64,
}

impl Line2 {
    /// The line through `a` and `b`, if they are apart.
    pub fn new(a: [f64; 2], b: [f64; 2]) -> Option<Self> {
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        (len > 1e-12).then(|| Line2 {
            a,
            dir: [(b[0] - a[0]) / len, (b[1] - a[1]) / len],
            len,
        })
    }

    /// Signed distance of `q` from the line, mm.
    pub fn across(&self, q: [f64; 2]) -> f64 {
        (q[0] - self.a[0]) * -self.dir[1] + (q[1] - self.a[1]) * self.dir[0]
    }

    /// Position of `q`'s foot along the line from `a`, mm.
    pub fn along(&self, q: [f64; 2]) -> f64 {
        (q[0] - self.a[0]) * self.dir[0] + (q[1] - self.a[1]) * self.dir[1]
    }

    /// Overlap of the segment `s` with `a`–`b` along the line, as a share of the shorter of the two.
    pub fn overlap_share(&self, s: [[f64; 2]; 2]) -> f64 {
        let (t0, t1) = (self.along(s[0]), self.along(s[1]));
        let (lo, hi) = (t0.min(t1), t0.max(t1));
        let overlap = hi.min(self.len) - lo.max(0.0);
        overlap / (hi - lo).min(self.len).max(1e-12)
    }
}
