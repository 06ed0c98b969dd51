//! Segment geometry shared by the 2-D and 3-D metrics (any dimension through nalgebra vectors).
use lineflow_photogrammetry::Vec3;

/// A segment in object space (metres) or in the image plane (z = 0, corrected pixels).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seg {
    pub a: Vec3,
    pub b: Vec3,
}

impl Seg {
    pub fn new(a: Vec3, b: Vec3) -> Seg {
        Seg { a, b }
    }
    pub fn length(&self) -> f64 {
        (self.b - self.a).norm()
    }
    pub fn dir(&self) -> Vec3 {
        (self.b - self.a).normalize()
    }
    pub fn at(&self, s: f64) -> Vec3 {
        self.a + (self.b - self.a) * s
    }
    /// Parameter of the closest point on the infinite line.
    pub fn param(&self, p: &Vec3) -> f64 {
        let d = self.b - self.a;
        (p - self.a).dot(&d) / d.norm_squared().max(1e-300)
    }
    /// Distance from a point to the segment.
    pub fn distance(&self, p: &Vec3) -> f64 {
        (p - self.at(self.param(p).clamp(0.0, 1.0))).norm()
    }
    /// Perpendicular distance from a point to the infinite line.
    pub fn line_distance(&self, p: &Vec3) -> f64 {
        (p - self.at(self.param(p))).norm()
    }
    /// Acute angle between the two directions, degrees.
    pub fn angle_deg(&self, other: &Seg) -> f64 {
        self.dir().dot(&other.dir()).abs().min(1.0).acos().to_degrees()
    }
    /// `n` sample points at the centres of equal parts, with the length each stands for.
    pub fn samples(&self, n: usize) -> impl Iterator<Item = (Vec3, f64)> + '_ {
        let w = self.length() / n as f64;
        (0..n).map(move |k| (self.at((k as f64 + 0.5) / n as f64), w))
    }
}

/// Orientation class of a 3-D segment (Z up).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    Horizontal,
    Vertical,
    Oblique,
    /// Horizontal, along the normal of the wall it is nearest to: the depth of a reveal, sill, lintel, cornice or
    /// frame, what makes a façade LOD 3 ([`class_on_walls`]).
    Depth,
}

/// A wall plane of the truth: its unit normal and its corners.
#[derive(Debug, Clone)]
pub struct WallPlane {
    pub normal: Vec3,
    pub corners: Vec<Vec3>,
}

impl WallPlane {
    /// The wall through `corners` (at least three, not collinear).
    pub fn new(corners: Vec<Vec3>) -> Option<WallPlane> {
        let normal = (corners.get(1)? - corners[0])
            .cross(&(corners.get(2)? - corners[1]))
            .try_normalize(1e-12)?;
        Some(WallPlane { normal, corners })
    }
}

/// [`classify`], with horizontal segments that run along the normal of the nearest wall (closer than 45° to it)
/// told apart as [`Class::Depth`].
pub fn class_on_walls(s: &Seg, walls: &[WallPlane]) -> Class {
    let class = classify(s);
    if class != Class::Horizontal {
        return class;
    }
    let mid = s.at(0.5);
    let nearest = walls
        .iter()
        .min_by(|a, b| polygon_distance(&mid, &a.corners).total_cmp(&polygon_distance(&mid, &b.corners)));
    match nearest {
        Some(w) if s.dir().dot(&w.normal).abs() > std::f64::consts::FRAC_1_SQRT_2 => Class::Depth,
        _ => class,
    }
}

pub fn classify(s: &Seg) -> Class {
    let dz = s.dir().z.abs();
    if dz > 0.985 {
        Class::Vertical
    } else if dz < 0.17 {
        Class::Horizontal
    } else {
        Class::Oblique
    }
}

/// Mean, standard deviation and maximum (NaN for an empty set).
pub fn stats(v: &[f64]) -> (f64, f64, f64) {
    if v.is_empty() {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    (mean, var.sqrt(), v.iter().cloned().fold(f64::NEG_INFINITY, f64::max))
}

/// Distance from a point to a convex planar polygon.
pub fn polygon_distance(p: &Vec3, corners: &[Vec3]) -> f64 {
    let n = (corners[1] - corners[0]).cross(&(corners[2] - corners[0])).normalize();
    let h = (p - corners[0]).dot(&n);
    let q = p - n * h;
    let k = corners.len();
    let inside = (0..k).all(|i| (corners[(i + 1) % k] - corners[i]).cross(&(q - corners[i])).dot(&n) >= 0.0);
    if inside {
        return h.abs();
    }
    (0..k)
        .map(|i| Seg::new(corners[i], corners[(i + 1) % k]).distance(p))
        .fold(f64::INFINITY, f64::min)
}

/// A uniform grid over boxes, for "everything within R of this point" queries.
pub struct Grid {
    cell: f64,
    lo: Vec3,
    hi: Vec3,
    map: std::collections::HashMap<[i64; 3], Vec<u32>>,
}

impl Grid {
    /// A grid of `cell`-sized cells that only indexes the region [lo, hi].
    pub fn new(cell: f64, lo: Vec3, hi: Vec3) -> Grid {
        Grid {
            cell,
            lo,
            hi,
            map: Default::default(),
        }
    }

    fn key(&self, p: &Vec3) -> [i64; 3] {
        [
            (p.x / self.cell).floor() as i64,
            (p.y / self.cell).floor() as i64,
            (p.z / self.cell).floor() as i64,
        ]
    }

    /// Registers item `id` with bounding box [lo, hi] grown by `reach`.
    pub fn insert(&mut self, id: u32, lo: Vec3, hi: Vec3, reach: f64) {
        let lo = (lo - Vec3::repeat(reach)).sup(&self.lo);
        let hi = (hi + Vec3::repeat(reach)).inf(&self.hi);
        if lo.x > hi.x || lo.y > hi.y || lo.z > hi.z {
            return;
        }
        let (a, b) = (self.key(&lo), self.key(&hi));
        for x in a[0]..=b[0] {
            for y in a[1]..=b[1] {
                for z in a[2]..=b[2] {
                    self.map.entry([x, y, z]).or_default().push(id);
                }
            }
        }
    }

    /// Items whose grown box may contain `p`.
    pub fn near(&self, p: &Vec3) -> &[u32] {
        self.map.get(&self.key(p)).map_or(&[], |v| v.as_slice())
    }
}

/// Bounding box of points.
pub fn bounds<'a>(points: impl IntoIterator<Item = &'a Vec3>) -> (Vec3, Vec3) {
    points
        .into_iter()
        .fold((Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY)), |(lo, hi), p| {
            (lo.inf(p), hi.sup(p))
        })
}

/// Segments indexed for distance queries up to `reach`.
pub fn segment_grid(set: &[Seg], reach: f64, region: (Vec3, Vec3)) -> Grid {
    let mut grid = Grid::new(reach.max(0.25), region.0, region.1);
    for (i, s) in set.iter().enumerate() {
        let (lo, hi) = bounds([&s.a, &s.b]);
        grid.insert(i as u32, lo, hi, reach);
    }
    grid
}
