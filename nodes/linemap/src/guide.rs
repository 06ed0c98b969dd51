//! What the site model tells the mapping: the region worth searching, and the directions a façade's edges take
//! (the vertical, and along and across each wall). Neither bounds what is reconstructed beyond that region's
//! margin or forces a direction: a line takes a direction only where its own estimate already lies close to it.
use lineflow_photogrammetry::Vec3;

use crate::hypotheses::Bounds;

/// The search region and the preferred directions.
#[derive(Debug, Clone, PartialEq)]
pub struct Guide {
    /// Where lines are sought; everywhere in front of the cameras when `None`.
    pub bounds: Option<Bounds>,
    /// Unit directions (up to sign) a line may be snapped to.
    pub directions: Vec<Vec3>,
}

impl Default for Guide {
    /// No site model: no bounds, and only the vertical.
    fn default() -> Self {
        Guide {
            bounds: None,
            directions: vec![Vec3::z()],
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
        }
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

/// The unit normal of a planar polygon (Newell's method), if it has an area.
fn polygon_normal(corners: &[Vec3]) -> Option<Vec3> {
    let n = corners.iter().zip(corners.iter().cycle().skip(1)).fold(Vec3::zeros(), |acc, (a, b)| acc + a.cross(b));
    n.try_normalize(1e-12)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wall_gives_its_horizontal_and_its_normal_beside_the_vertical() {
        let wall = vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(10.0, 0.0, 0.0), Vec3::new(10.0, 0.0, 5.0), Vec3::new(0.0, 0.0, 5.0)];
        let g = Guide::from_walls(&[wall.clone(), wall], 1.0);
        assert_eq!(g.directions.len(), 3, "{:?}", g.directions);
        let tilted = Vec3::new(1.0, 0.05, 0.0);
        assert!((g.snap(&tilted, 3.0).unwrap().x.abs() - 1.0).abs() < 1e-12);
        assert!(g.snap(&Vec3::new(1.0, 0.0, 1.0), 3.0).is_none());
        let b = g.bounds.unwrap();
        assert_eq!((b.lo, b.hi), (Vec3::new(-1.0, -1.0, -1.0), Vec3::new(11.0, 1.0, 6.0)));
        assert_eq!(Guide::default().snap(&Vec3::new(0.01, 0.0, 1.0), 1.0), Some(Vec3::z()));
    }
}
