//! What the site model tells the mapping: the region worth searching, and the directions a façade's edges take
//! (the vertical, and along and across each wall). Neither bounds what is reconstructed beyond that region's
//! margin or forces a direction: a line takes a direction only where its own estimate already lies close to it.
use lineflow_photogrammetry::{point_in_polygon, polygon_normal, Vec3};

/// The region where lines are sought, an axis-aligned box (the site model's walls grown by a margin), or none.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// Lowest corner.
    pub lo: Vec3,
    /// Highest corner.
    pub hi: Vec3,
}

impl Bounds {
    /// The box around `points` grown by `margin` metres, if there are any points.
    pub fn around(points: impl IntoIterator<Item = Vec3>, margin: f64) -> Option<Bounds> {
        let mut it = points.into_iter();
        let first = it.next()?;
        let (lo, hi) = it.fold((first, first), |(lo, hi), p| (lo.inf(&p), hi.sup(&p)));
        let m = Vec3::repeat(margin);
        Some(Bounds { lo: lo - m, hi: hi + m })
    }

    /// The ray parameters (distances along the unit ray `dir` from `origin`) inside the box.
    pub fn clip(&self, origin: &Vec3, dir: &Vec3) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
        for k in 0..3 {
            if dir[k].abs() < 1e-15 {
                if origin[k] < self.lo[k] || origin[k] > self.hi[k] {
                    return None;
                }
                continue;
            }
            let (a, b) = ((self.lo[k] - origin[k]) / dir[k], (self.hi[k] - origin[k]) / dir[k]);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
        (t1 > t0).then_some((t0, t1))
    }
}

/// The search region and the preferred directions.
#[derive(Debug, Clone, PartialEq)]
pub struct Guide {
    /// Where lines are sought; everywhere in front of the cameras when `None`.
    pub bounds: Option<Bounds>,
    /// Unit directions (up to sign) a line may be snapped to.
    pub directions: Vec<Vec3>,
    /// The walls, as occluders.
    walls: Vec<Wall>,
}

/// A wall of the site model: its outward unit normal, a point on it, two axes in it and its outline on them.
#[derive(Debug, Clone, PartialEq)]
struct Wall {
    normal: Vec3,
    origin: Vec3,
    axes: [Vec3; 2],
    outline: Vec<[f64; 2]>,
}

impl Wall {
    fn new(corners: &[Vec3]) -> Option<Wall> {
        let normal = polygon_normal(corners)?;
        let origin = corners[0];
        let u = (corners[1] - origin).try_normalize(1e-12)?;
        let axes = [u, normal.cross(&u)];
        let outline = corners.iter().map(|c| axes.map(|a| a.dot(&(c - origin)))).collect();
        Some(Wall {
            normal,
            origin,
            axes,
            outline,
        })
    }

    /// Signed distance of `p` in front of the wall, if `p` lies over its outline.
    fn in_front(&self, p: &Vec3) -> Option<f64> {
        self.in_front_within(p, 0.0)
    }

    /// Signed distance of `p` in front of the wall, if `p` lies over its outline grown by `margin` metres.
    fn in_front_within(&self, p: &Vec3, margin: f64) -> Option<f64> {
        let q = self.axes.map(|a| a.dot(&(p - self.origin)));
        let over = point_in_polygon(q, &self.outline) || (margin > 0.0 && outline_distance(q, &self.outline) <= margin);
        over.then(|| self.normal.dot(&(p - self.origin)))
    }
}

impl Default for Guide {
    /// No site model: no bounds, and only the vertical.
    fn default() -> Self {
        Guide {
            bounds: None,
            directions: vec![Vec3::z()],
            walls: Vec::new(),
        }
    }
}

impl Guide {
    /// The guide of a site model's walls (corner lists), searching within `margin_m` of them.
    pub fn from_walls(walls: &[Vec<Vec3>], margin_m: f64) -> Guide {
        let mut directions = vec![Vec3::z()];
        for corners in walls {
            let Some(normal) = polygon_normal(corners) else { continue };
            let across = Vec3::new(normal.x, normal.y, 0.0);
            let Some(across) = across.try_normalize(1e-9) else { continue };
            for d in [across, Vec3::z().cross(&across)] {
                if directions.iter().all(|e| e.dot(&d).abs() < (0.5f64).to_radians().cos()) {
                    directions.push(d);
                }
            }
        }
        Guide {
            bounds: Bounds::around(walls.iter().flatten().copied(), margin_m),
            directions,
            walls: walls.iter().filter_map(|c| Wall::new(c)).collect(),
        }
    }

    /// The weight of a hypothesis by where it lies: 1 within `near_m` of a wall it lies over (its outline grown by
    /// `near_m`) or over no wall at all (roofs, ground, or no site model), `off_weight` elsewhere. Among rival
    /// depths of one segment that the images confirm alike (brick courses matched one course off across strips),
    /// the one on the wall wins; a line well off every wall (an eave, a balcony) still wins over rivals that the
    /// images confirm less.
    pub fn placement_weight(&self, ends: &[Vec3; 2], near_m: f64, off_weight: f64) -> f64 {
        let near = |p: &Vec3| {
            let mut d = self.walls.iter().filter_map(|w| w.in_front_within(p, near_m)).peekable();
            d.peek().is_none() || d.any(|d| d.abs() <= near_m)
        };
        if ends.iter().all(near) {
            1.0
        } else {
            off_weight
        }
    }

    /// Whether `p` lies inside the building, more than `depth_m` behind every wall it lies over: no image taken
    /// from outside sees it (walls are opaque; openings are shallower than that).
    pub fn hidden(&self, p: &Vec3, depth_m: f64) -> bool {
        let mut over = self.walls.iter().filter_map(|w| w.in_front(p)).peekable();
        over.peek().is_some() && over.all(|d| d < -depth_m)
    }

    /// The walls' outward unit normals, in order.
    pub fn wall_normals(&self) -> impl Iterator<Item = Vec3> + '_ {
        self.walls.iter().map(|w| w.normal)
    }

    /// Signed distance of `p` in front of wall `wall`, if `p` lies over its outline grown by `margin` metres.
    pub fn in_front_of_wall(&self, wall: usize, p: &Vec3, margin: f64) -> Option<f64> {
        self.walls.get(wall)?.in_front_within(p, margin)
    }

    /// The preferred direction within `max_angle_deg` of `d` (closest first), if any.
    pub fn snap(&self, d: &Vec3, max_angle_deg: f64) -> Option<Vec3> {
        let d = d.try_normalize(1e-12)?;
        let min_cos = max_angle_deg.to_radians().cos();
        self.directions
            .iter()
            .map(|e| (e, e.dot(&d).abs()))
            .filter(|(_, c)| *c >= min_cos)
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(e, _)| *e)
    }
}

/// Distance of `q` from the closed outline `poly`.
fn outline_distance(q: [f64; 2], poly: &[[f64; 2]]) -> f64 {
    poly.iter()
        .zip(poly.iter().cycle().skip(1))
        .map(|(a, b)| {
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let t = (((q[0] - a[0]) * dx + (q[1] - a[1]) * dy) / (dx * dx + dy * dy).max(1e-300)).clamp(0.0, 1.0);
            (q[0] - a[0] - t * dx).hypot(q[1] - a[1] - t * dy)
        })
        .fold(f64::INFINITY, f64::min)
}

/// A wall y = 0 from x = 0 to 20 m, 10 m high, facing −y (the cameras), searched within 3 m: the tests' façade.
#[cfg(test)]
pub(crate) fn one_wall() -> Guide {
    let corners = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(20.0, 0.0, 0.0),
        Vec3::new(20.0, 0.0, 10.0),
        Vec3::new(0.0, 0.0, 10.0),
    ];
    Guide::from_walls(&[corners], 3.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wall_gives_its_horizontal_and_its_normal_beside_the_vertical() {
        let wall = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(10.0, 0.0, 5.0),
            Vec3::new(0.0, 0.0, 5.0),
        ];
        let g = Guide::from_walls(&[wall.clone(), wall], 1.0);
        assert_eq!(g.directions.len(), 3, "{:?}", g.directions);
        let tilted = Vec3::new(1.0, 0.05, 0.0);
        assert!((g.snap(&tilted, 3.0).unwrap().x.abs() - 1.0).abs() < 1e-12);
        assert!(g.snap(&Vec3::new(1.0, 0.0, 1.0), 3.0).is_none());
        let b = g.bounds.unwrap();
        assert_eq!((b.lo, b.hi), (Vec3::new(-1.0, -1.0, -1.0), Vec3::new(11.0, 1.0, 6.0)));
        assert_eq!(Guide::default().snap(&Vec3::new(0.01, 0.0, 1.0), 1.0), Some(Vec3::z()));
    }

    #[test]
    fn a_point_deep_inside_a_box_is_hidden_and_one_in_front_or_in_a_reveal_is_not() {
        // A 10 × 6 × 5 m box, each wall counter-clockwise seen from outside.
        let c = |x: f64, y: f64, z: f64| Vec3::new(x, y, z);
        let walls = vec![
            vec![c(0.0, 0.0, 0.0), c(10.0, 0.0, 0.0), c(10.0, 0.0, 5.0), c(0.0, 0.0, 5.0)],
            vec![c(10.0, 0.0, 0.0), c(10.0, 6.0, 0.0), c(10.0, 6.0, 5.0), c(10.0, 0.0, 5.0)],
            vec![c(10.0, 6.0, 0.0), c(0.0, 6.0, 0.0), c(0.0, 6.0, 5.0), c(10.0, 6.0, 5.0)],
            vec![c(0.0, 6.0, 0.0), c(0.0, 0.0, 0.0), c(0.0, 0.0, 5.0), c(0.0, 6.0, 5.0)],
        ];
        let g = Guide::from_walls(&walls, 1.0);
        assert!(g.hidden(&c(5.0, 3.0, 2.0), 1.0));
        assert!(!g.hidden(&c(5.0, 0.5, 2.0), 1.0), "a reveal half a metre deep");
        assert!(!g.hidden(&c(5.0, -2.0, 2.0), 1.0), "in front of the façade");
        assert!(!g.hidden(&c(5.0, 3.0, 7.0), 1.0), "above the walls (a roof)");
        assert!(!Guide::default().hidden(&c(5.0, 3.0, 2.0), 1.0));
    }
}
